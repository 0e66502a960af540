//! Changes to a configuration file that keep the rest of it as written (comments, order,
//! layout): the fixes `videt commission` finds, applied to a copy of the file.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::Config;

/// A value a fix gives a key (or one element of an array key). Serialized as the plain value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum FixValue {
    /// A boolean.
    Bool(bool),
    /// An integer.
    Integer(i64),
    /// A float.
    Float(f64),
    /// A string.
    Text(String),
    /// An array.
    List(Vec<FixValue>),
}

impl FixValue {
    fn to_item(&self) -> toml_edit::Value {
        match self {
            FixValue::Bool(b) => (*b).into(),
            FixValue::Integer(i) => (*i).into(),
            FixValue::Float(f) => (*f).into(),
            FixValue::Text(t) => t.as_str().into(),
            FixValue::List(l) => toml_edit::Value::Array(l.iter().map(FixValue::to_item).collect()),
        }
    }
}

impl fmt::Display for FixValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FixValue::Bool(b) => write!(f, "{b}"),
            FixValue::Integer(i) => write!(f, "{i}"),
            FixValue::Float(x) => write!(f, "{x:e}"),
            FixValue::Text(t) => write!(f, "{t:?}"),
            FixValue::List(l) => {
                let items: Vec<String> = l.iter().map(ToString::to_string).collect();
                write!(f, "[{}]", items.join(", "))
            }
        }
    }
}

/// A configuration change: `key` (`section.name`), the element `index` of an array key or the
/// whole key, and its new value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fix {
    /// `section.name`, e.g. `drives.motor_reversed`.
    pub key: String,
    /// The array element, or `None` for the whole key.
    pub index: Option<usize>,
    /// The new value.
    pub value: FixValue,
}

impl Fix {
    /// A fix of `key` (element `index`) to `value`.
    pub fn new(key: impl Into<String>, index: Option<usize>, value: FixValue) -> Fix {
        Fix {
            key: key.into(),
            index,
            value,
        }
    }
}

impl fmt::Display for Fix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.index {
            Some(i) => write!(f, "{}[{i}] = {}", self.key, self.value),
            None => write!(f, "{} = {}", self.key, self.value),
        }
    }
}

/// Apply `fixes` in order to the configuration file `text` whose settings are `config` (an
/// array key the file leaves out is written whole, from `config`, before its element is
/// changed). Everything else in the file stays as written. The result must load: an error
/// names the fix that cannot be made, or what the result breaks.
pub fn apply_fixes(text: &str, config: &Config, fixes: &[Fix]) -> Result<String, String> {
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .map_err(|e| format!("the configuration is not TOML: {e}"))?;
    let current = toml::Value::try_from(config).map_err(|e| e.to_string())?;
    for fix in fixes {
        let (section, name) = fix
            .key
            .split_once('.')
            .ok_or_else(|| format!("{fix}: not a section.key"))?;
        let table = doc
            .entry(section)
            .or_insert_with(toml_edit::table)
            .as_table_like_mut()
            .ok_or_else(|| format!("{fix}: [{section}] is not a table"))?;
        match fix.index {
            None => match table.get_mut(name).and_then(|i| i.as_value_mut()) {
                // The key's comments and spacing stay.
                Some(v) => {
                    let decor = v.decor().clone();
                    *v = fix.value.to_item();
                    *v.decor_mut() = decor;
                }
                None => {
                    table.insert(name, toml_edit::value(fix.value.to_item()));
                }
            },
            Some(i) => {
                if table.get(name).is_none() {
                    let whole = current
                        .get(section)
                        .and_then(|s| s.get(name))
                        .ok_or_else(|| format!("{fix}: no such key"))?;
                    let value: toml_edit::Value = whole
                        .to_string()
                        .parse()
                        .map_err(|e| format!("{fix}: {e}"))?;
                    table.insert(name, toml_edit::value(value));
                }
                let array = table
                    .get_mut(name)
                    .and_then(|v| v.as_array_mut())
                    .ok_or_else(|| format!("{fix}: {} is not an array", fix.key))?;
                let slot = array
                    .get_mut(i)
                    .ok_or_else(|| format!("{fix}: {} has no element {i}", fix.key))?;
                // The element's own comments and spacing stay.
                let decor = slot.decor().clone();
                *slot = fix.value.to_item();
                *slot.decor_mut() = decor;
            }
        }
    }
    let out = doc.to_string();
    let fixed: Config =
        toml::from_str(&out).map_err(|e| format!("the fixed configuration does not load: {e}"))?;
    fixed
        .validate()
        .map_err(|e| format!("the fixed configuration is not valid: {e}"))?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixes_serialize_and_come_back_the_same() {
        let fixes = vec![
            Fix::new("drives.motor_reversed", Some(1), FixValue::Bool(true)),
            node_order([3, 1, 2]),
            Fix::new("sensors.newtons_per_count", Some(2), FixValue::Float(-2.0)),
            Fix::new("sensors.zero_counts", Some(0), FixValue::Float(1.25e-3)),
            Fix::new(
                "sensors.estop_pressed_level",
                None,
                FixValue::Text("high".into()),
            ),
        ];
        let text = toml::to_string(&Wrapper {
            fixes: fixes.clone(),
        })
        .unwrap();
        let back: Wrapper = toml::from_str(&text).unwrap();
        assert_eq!(back.fixes, fixes, "{text}");
    }

    /// The fix of `drives.node_ids` to `ids`.
    fn node_order(ids: [i64; 3]) -> Fix {
        let ids = ids.iter().map(|&i| FixValue::Integer(i)).collect();
        Fix::new("drives.node_ids", None, FixValue::List(ids))
    }

    /// A document holding fixes (TOML has no top-level arrays).
    #[derive(Serialize, Deserialize)]
    struct Wrapper {
        fixes: Vec<Fix>,
    }

    const FILE: &str = "# The rig on the bench.\n[drives]\n# ids as wired\nnode_ids = [1, 2, 3]   # wires 0, 1, 2\nmotor_reversed = [false, false, false]\n\n[sensors]\nestop_line = 17 # input\n";

    #[test]
    fn fixes_change_only_their_keys_and_keep_the_comments() {
        let config: Config = toml::from_str(FILE).unwrap();
        let fixes = [
            Fix::new("drives.motor_reversed", Some(1), FixValue::Bool(true)),
            node_order([3, 2, 1]),
            // Keys the file leaves out: written whole from the settings, then fixed.
            Fix::new("drives.encoder_reversed", Some(2), FixValue::Bool(true)),
            Fix::new(
                "sensors.newtons_per_count",
                Some(0),
                FixValue::Float(-2.33e-5),
            ),
            Fix::new(
                "sensors.estop_pressed_level",
                None,
                FixValue::Text("high".into()),
            ),
        ];
        let out = apply_fixes(FILE, &config, &fixes).unwrap();
        for kept in [
            "# The rig on the bench.",
            "# ids as wired",
            "# wires 0, 1, 2",
            "estop_line = 17 # input",
        ] {
            assert!(out.contains(kept), "{kept:?} lost:\n{out}");
        }
        let fixed: Config = toml::from_str(&out).unwrap();
        assert_eq!(fixed.drives.node_ids, [3, 2, 1]);
        assert_eq!(fixed.drives.motor_reversed, [false, true, false]);
        assert_eq!(fixed.drives.encoder_reversed, [false, false, true]);
        assert_eq!(fixed.sensors.newtons_per_count[0], -2.33e-5);
        assert_eq!(fixed.sensors.newtons_per_count[1], 2.33e-5);
        assert_eq!(fixed.sensors.estop_pressed_level, crate::LineLevel::High);
        assert_eq!(fixes[0].to_string(), "drives.motor_reversed[1] = true");
        assert_eq!(fixes[1].to_string(), "drives.node_ids = [3, 2, 1]");
    }

    #[test]
    fn a_fix_that_cannot_be_made_or_breaks_the_file_is_an_error() {
        let config = Config::default();
        let bad = [Fix::new("drives.node_ids", Some(5), FixValue::Integer(4))];
        assert!(apply_fixes(FILE, &config, &bad)
            .unwrap_err()
            .contains("no element 5"));
        let twice = [Fix::new("drives.node_ids", Some(0), FixValue::Integer(2))];
        assert!(apply_fixes(FILE, &config, &twice)
            .unwrap_err()
            .contains("not valid"));
        assert!(apply_fixes("[drives", &config, &[]).is_err());
    }
}
