//! A reader for CANopen electronic data sheets (EDS) and device configuration files (DCF),
//! CiA 306 INI format: `[1018sub1]` sections with `ParameterName`, `DataType`, `AccessType`,
//! `DefaultValue` (and `ParameterValue` in a DCF). Accepts CRLF or LF line endings, comments
//! (`;` lines, `# ...` after a section header or a value), decimal and `0x` hex numbers, and
//! `$NODEID+0x..` / `0x..+$NODEID` expressions. **non-RT** (allocates).

use std::collections::BTreeMap;

/// An object dictionary entry as the data sheet describes it.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct EdsEntry {
    /// `ParameterName`.
    pub name: String,
    /// `ObjectType` (0x7 VAR, 0x8 ARRAY, 0x9 RECORD), when given.
    pub object_type: Option<u8>,
    /// `DataType` (CiA 301 index: 0x0006 UNSIGNED16, ...), when given.
    pub data_type: Option<u16>,
    /// `AccessType` (`ro`, `rw`, `wo`, `const`, `rww`, `rwr`), lower-cased.
    pub access: Option<String>,
    /// `DefaultValue`, raw text.
    pub default_value: Option<String>,
    /// `ParameterValue` (DCF), raw text.
    pub parameter_value: Option<String>,
    /// `PDOMapping=1`.
    pub pdo_mappable: bool,
}

/// An error reading a data sheet, with the 1-based line it was found on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum EdsError {
    /// A section header that is neither a known name nor `[iiii]` / `[iiiisubS]`.
    #[error("line {line}: bad section header {text:?} (expected [IIII] or [IIIIsubS], hex)")]
    BadSection {
        /// Line number.
        line: usize,
        /// The header text.
        text: String,
    },
    /// A value of a numeric key that is not a number.
    #[error("line {line}: {key}={value:?} is not a number (decimal, 0x hex, or $NODEID+..)")]
    BadNumber {
        /// Line number.
        line: usize,
        /// Key.
        key: String,
        /// Value.
        value: String,
    },
    /// A numeric expression that is not a number.
    #[error("{value:?} is not a number (decimal, 0x hex, or $NODEID+..)")]
    BadValue {
        /// The value text.
        value: String,
    },
}

/// A parsed data sheet: the object dictionary entries by `(index, subindex)`.
#[derive(Debug, Clone, Default)]
pub struct Eds {
    entries: BTreeMap<(u16, u8), EdsEntry>,
    /// `[DeviceInfo] ProductName`, when given.
    pub product_name: Option<String>,
    /// `[DeviceInfo] VendorName`, when given.
    pub vendor_name: Option<String>,
    /// `[DeviceInfo] VendorNumber` (the CiA-assigned vendor id, as in 0x1018 sub 1), when
    /// given and a number.
    pub vendor_number: Option<u32>,
    /// `[DeviceInfo] ProductNumber` (the product code, as in 0x1018 sub 2), when given and a
    /// number.
    pub product_number: Option<u32>,
}

/// Parse a numeric EDS value: decimal (optionally negative), `0x` hex, octal with a leading
/// `0` (CiA 306), `$NODEID` alone or added to a number on either side.
pub fn parse_value(text: &str, node_id: u8) -> Result<i128, EdsError> {
    let bad = || EdsError::BadValue {
        value: text.to_string(),
    };
    let t = text.trim();
    if t.is_empty() {
        return Err(bad());
    }
    let mut total: i128 = 0;
    for term in t.split('+') {
        let term = term.trim();
        if term.eq_ignore_ascii_case("$NODEID") {
            total = total.checked_add(i128::from(node_id)).ok_or_else(bad)?;
            continue;
        }
        let (neg, digits) = match term.strip_prefix('-') {
            Some(d) => (true, d),
            None => (false, term),
        };
        let v = if let Some(h) = digits
            .strip_prefix("0x")
            .or_else(|| digits.strip_prefix("0X"))
        {
            i128::from_str_radix(h, 16).map_err(|_| bad())?
        } else if digits.len() > 1 && digits.starts_with('0') {
            i128::from_str_radix(&digits[1..], 8).map_err(|_| bad())?
        } else {
            digits.parse::<i128>().map_err(|_| bad())?
        };
        total = total
            .checked_add(if neg { -v } else { v })
            .ok_or_else(bad)?;
    }
    Ok(total)
}

fn parse_section(name: &str) -> Option<(u16, u8)> {
    let lower = name.to_ascii_lowercase();
    let (idx, sub) = match lower.split_once("sub") {
        Some((i, s)) => (i, Some(s)),
        None => (lower.as_str(), None),
    };
    if idx.len() != 4 {
        return None;
    }
    let index = u16::from_str_radix(idx, 16).ok()?;
    let sub = match sub {
        Some(s) if !s.is_empty() && s.len() <= 2 => u8::from_str_radix(s, 16).ok()?,
        Some(_) => return None,
        None => 0,
    };
    Some((index, sub))
}

impl Eds {
    /// Parse the text of an EDS or DCF.
    pub fn parse(text: &str) -> Result<Eds, EdsError> {
        let mut eds = Eds::default();
        // Where the current section's keys go.
        enum Target {
            Entry((u16, u8)),
            DeviceInfo,
            Ignored,
        }
        let mut target = Target::Ignored;
        for (i, raw) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = raw.trim_end_matches('\r').trim();
            if line.is_empty() || line.starts_with(';') {
                continue;
            }
            if let Some(rest) = line.strip_prefix('[') {
                let Some((name, _comment)) = rest.split_once(']') else {
                    return Err(EdsError::BadSection {
                        line: line_no,
                        text: line.to_string(),
                    });
                };
                let name = name.trim();
                target = match parse_section(name) {
                    Some(key) => {
                        eds.entries.entry(key).or_default();
                        Target::Entry(key)
                    }
                    None if name.eq_ignore_ascii_case("DeviceInfo") => Target::DeviceInfo,
                    None if !name
                        .get(..4)
                        .is_some_and(|p| p.chars().all(|c| c.is_ascii_hexdigit()))
                        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') =>
                    {
                        Target::Ignored
                    }
                    None => {
                        return Err(EdsError::BadSection {
                            line: line_no,
                            text: line.to_string(),
                        })
                    }
                };
                continue;
            }
            let Some((key, value)) = line.split_once('=') else {
                continue; // not a key=value line: tolerated as a comment
            };
            // A trailing ` # comment` (seen in generic sample sheets) is not part of the value.
            let value = match value.find(" #").or_else(|| value.find("\t#")) {
                Some(cut) => &value[..cut],
                None => value,
            };
            let (key, value) = (key.trim(), value.trim());
            let number = |v: &str| -> Result<i128, EdsError> {
                parse_value(v, 0).map_err(|_| EdsError::BadNumber {
                    line: line_no,
                    key: key.to_string(),
                    value: v.to_string(),
                })
            };
            match &target {
                Target::DeviceInfo => match key.to_ascii_lowercase().as_str() {
                    "productname" => eds.product_name = Some(value.to_string()),
                    "vendorname" => eds.vendor_name = Some(value.to_string()),
                    "vendornumber" => {
                        eds.vendor_number = parse_value(value, 0)
                            .ok()
                            .and_then(|v| u32::try_from(v).ok())
                    }
                    "productnumber" => {
                        eds.product_number = parse_value(value, 0)
                            .ok()
                            .and_then(|v| u32::try_from(v).ok())
                    }
                    _ => {}
                },
                Target::Entry(k) => {
                    let e = eds.entries.get_mut(k).expect("inserted at the header");
                    match key.to_ascii_lowercase().as_str() {
                        "parametername" => e.name = value.to_string(),
                        "objecttype" => e.object_type = Some(number(value)? as u8),
                        "datatype" => e.data_type = Some(number(value)? as u16),
                        "accesstype" => e.access = Some(value.to_ascii_lowercase()),
                        "defaultvalue" => e.default_value = Some(value.to_string()),
                        "parametervalue" => e.parameter_value = Some(value.to_string()),
                        "pdomapping" => e.pdo_mappable = number(value)? != 0,
                        _ => {}
                    }
                }
                Target::Ignored => {}
            }
        }
        Ok(eds)
    }

    /// The entry at `(index, subindex)`.
    pub fn entry(&self, index: u16, subindex: u8) -> Option<&EdsEntry> {
        self.entries.get(&(index, subindex))
    }

    /// Every entry, in index order.
    pub fn entries(&self) -> impl Iterator<Item = (&(u16, u8), &EdsEntry)> {
        self.entries.iter()
    }

    /// The configured value of an entry as a number for node `node_id`: the DCF's
    /// `ParameterValue` when present and not empty, else the `DefaultValue`. `Ok(None)` when the
    /// entry or both values are absent or empty.
    pub fn value(&self, index: u16, subindex: u8, node_id: u8) -> Result<Option<i128>, EdsError> {
        let Some(e) = self.entry(index, subindex) else {
            return Ok(None);
        };
        let text = [e.parameter_value.as_deref(), e.default_value.as_deref()]
            .into_iter()
            .flatten()
            .map(str::trim)
            .find(|v| !v.is_empty());
        match text {
            None => Ok(None),
            Some(v) => parse_value(v, node_id).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_numbers_in_every_eds_spelling() {
        assert_eq!(parse_value("0x180", 0).unwrap(), 0x180);
        assert_eq!(parse_value("$NODEID+0x180", 5).unwrap(), 0x185);
        assert_eq!(parse_value("0x580+$NODEID", 3).unwrap(), 0x583);
        assert_eq!(parse_value("$NODEID+0x40000180", 1).unwrap(), 0x4000_0181);
        assert_eq!(parse_value("-2147483648", 0).unwrap(), -2_147_483_648);
        assert_eq!(parse_value("1000", 0).unwrap(), 1000);
        assert_eq!(parse_value("010", 0).unwrap(), 8);
        assert_eq!(parse_value("0", 0).unwrap(), 0);
        assert!(parse_value("0 or profile-specific", 0).is_err());
        assert!(parse_value("", 0).is_err());
    }

    #[test]
    fn sums_beyond_the_number_range_are_bad_values_not_a_panic() {
        // The terms' sum overflowed (a panic with overflow checks, a wrapped value without);
        // read in the code, confirmed with the eds_parse fuzz target.
        let max = "0x7FFFFFFFFFFFFFFFFFFFFFFFFFFFFFFF";
        assert_eq!(parse_value(max, 0).unwrap(), i128::MAX);
        assert!(parse_value(&format!("{max}+1"), 0).is_err());
        assert!(parse_value(&format!("{max}+$NODEID"), 5).is_err());
        let min = "-99999999999999999999999999999999999999";
        assert!(parse_value(&format!("{min}+{min}+{min}"), 0).is_err());
        let eds = Eds::parse(&format!("[1000]\nDefaultValue={max}+1\n")).unwrap();
        assert!(eds.value(0x1000, 0, 1).is_err());
        let e = Eds::parse(&format!("[1000]\nObjectType={max}+1\n")).unwrap_err();
        assert!(matches!(e, EdsError::BadNumber { line: 2, .. }), "{e}");
    }

    #[test]
    fn parses_crlf_sections_subindices_and_comments() {
        let text = "[DeviceInfo]\r\nProductName=Drive X\r\n\r\n[1017]\r\nParameterName=Producer heartbeat time\r\nObjectType=0x07 # VAR\r\nDataType=0x0006\r\nAccessType=RW\r\nDefaultValue=0\r\nPDOMapping=0\r\n[1800sub1] # comment\r\nParameterName=COB-ID\r\nDataType=0x0007\r\nDefaultValue=$NODEID+0x40000180\r\nParameterValue=0x181\r\n";
        let eds = Eds::parse(text).unwrap();
        assert_eq!(eds.product_name.as_deref(), Some("Drive X"));
        let e = eds.entry(0x1017, 0).unwrap();
        assert_eq!(e.data_type, Some(6));
        assert_eq!(e.access.as_deref(), Some("rw"));
        assert_eq!(eds.value(0x1800, 1, 4).unwrap(), Some(0x181));
        assert_eq!(eds.value(0x1017, 0, 4).unwrap(), Some(0));
        assert_eq!(eds.value(0x1234, 0, 4).unwrap(), None);
    }

    #[test]
    fn a_dcf_parameter_value_wins_over_the_default_unless_empty() {
        let text = "[DeviceInfo]\nVendorNumber=0x000000FB\n[6076]\nDefaultValue=0\nParameterValue=512871\n[6072]\nDefaultValue=1000\nParameterValue=\n[6073]\nParameterValue=\n";
        let eds = Eds::parse(text).unwrap();
        assert_eq!(eds.vendor_number, Some(0xFB));
        assert_eq!(eds.value(0x6076, 0, 1).unwrap(), Some(512_871));
        assert_eq!(eds.value(0x6072, 0, 1).unwrap(), Some(1000));
        assert_eq!(eds.value(0x6073, 0, 1).unwrap(), None);
    }

    #[test]
    fn bad_headers_and_numbers_name_the_line() {
        let e = Eds::parse("[1017subZ]\nDataType=1\n").unwrap_err();
        assert!(matches!(e, EdsError::BadSection { line: 1, .. }), "{e}");
        let e = Eds::parse("[1017]\nDataType=seven\n").unwrap_err();
        assert!(matches!(e, EdsError::BadNumber { line: 2, .. }), "{e}");
    }
}
