//! The simulated drive's object dictionary as a part's description gives it: which objects and
//! sub-indices exist, their data types, access and PDO mappability, and their defaults; and
//! the CiA 301 answers a drive gives to SDO requests the dictionary does not allow, which the
//! SDO server of `canopen-rs` does not tell apart (object or sub-index absent, length
//! mismatch, read-only, write-only, not mappable, mapping changed while its PDO is valid,
//! mapping too long, a mode of operation the drive does not support).
//!
//! Two dictionaries exist: [`DriveDictionary::generic`], the built-in CiA 402 profile of the
//! twin, and one read from a drive's EDS or DCF (built by the runtime, which reads the file).

use canopen_rs::{Address, ByteString, Entry, ObjectDictionary, Value};

/// Object dictionary capacity of the simulated drive: room for a real drive's DCF.
pub const OD_CAPACITY: usize = 1024;

/// CiA 301 SDO abort codes the dictionary answers with.
pub mod abort {
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Attempt to read a write-only object.
    pub const WRITE_ONLY: u32 = 0x0601_0001;
    /// Attempt to write a read-only object.
    pub const READ_ONLY: u32 = 0x0601_0002;
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const MAPPING_TOO_LONG: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter does not match.
    pub const LENGTH_MISMATCH: u32 = 0x0607_0010;
    /// Sub-index does not exist.
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    /// Invalid value for parameter.
    pub const INVALID_VALUE: u32 = 0x0609_0030;
}

/// SDO access of an object.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectAccess {
    /// Read-only (`ro`).
    ReadOnly,
    /// Write-only (`wo`).
    WriteOnly,
    /// Read-write (`rw`, `rww`, `rwr`).
    ReadWrite,
    /// Constant (`const`).
    Const,
}

impl ObjectAccess {
    /// The access of an EDS `AccessType` (case-insensitive; an unknown one is read-write).
    pub fn from_eds(text: &str) -> ObjectAccess {
        match text.trim().to_ascii_lowercase().as_str() {
            "ro" => ObjectAccess::ReadOnly,
            "wo" => ObjectAccess::WriteOnly,
            "const" => ObjectAccess::Const,
            _ => ObjectAccess::ReadWrite,
        }
    }
}

/// An object's default value: a number, possibly plus the node id (`$NODEID+...`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DefaultValue {
    /// The value for node id 0.
    pub value: i128,
    /// Whether the node id is added to it.
    pub plus_node_id: bool,
}

impl DefaultValue {
    /// The value on node `node_id`.
    pub fn at(&self, node_id: u8) -> i128 {
        self.value
            + if self.plus_node_id {
                i128::from(node_id)
            } else {
                0
            }
    }
}

/// One object (index and sub-index) of the dictionary.
#[derive(Debug, Clone, PartialEq)]
pub struct DescribedObject {
    /// Index.
    pub index: u16,
    /// Sub-index.
    pub subindex: u8,
    /// CiA 301 data type (0x0007 UNSIGNED32, ...); `None` for a record's or array's header.
    pub data_type: Option<u16>,
    /// SDO access.
    pub access: ObjectAccess,
    /// May be mapped into a PDO.
    pub pdo_mappable: bool,
    /// Default (or, from a DCF, configured) value.
    pub default: Option<DefaultValue>,
    /// Default text of a string object.
    pub text: Option<String>,
}

/// The dictionary of a simulated drive and the units it gives its values in.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveDictionary {
    /// Where it comes from (a file name, or "generic CiA 402 profile").
    pub source: String,
    /// Every object, sorted by index then sub-index.
    pub objects: Vec<DescribedObject>,
    /// N·m per unit of the motor rated torque 0x6076 (1e-3 by CiA 402; 1e-6 on maxon drives).
    pub torque_unit_nm: f64,
    /// Encoder counts per unit of the position actual value 0x6064.
    pub counts_per_position_unit: f64,
    /// Counts per second per unit of the velocity actual value 0x606C.
    pub counts_per_s_per_velocity_unit: f64,
}

/// The analog inputs the simulated drive serves the plant's analog input at: CiA 401 "read
/// analog input 16-bit" sub 1, and the EPOS4's "analog input 1 voltage" 0x3160 sub 1.
pub const ANALOG_INPUTS: [(u16, u8); 2] = [(0x6401, 1), (0x3160, 1)];

fn described(
    index: u16,
    subindex: u8,
    data_type: u16,
    access: ObjectAccess,
    pdo_mappable: bool,
    value: i128,
    plus_node_id: bool,
) -> DescribedObject {
    DescribedObject {
        index,
        subindex,
        data_type: Some(data_type),
        access,
        pdo_mappable,
        default: Some(DefaultValue {
            value,
            plus_node_id,
        }),
        text: None,
    }
}

/// CiA 301 data type numbers.
mod ty {
    pub const U8: u16 = 0x05;
    pub const U16: u16 = 0x06;
    pub const U32: u16 = 0x07;
    pub const I8: u16 = 0x02;
    pub const I16: u16 = 0x03;
    pub const I32: u16 = 0x04;
}

impl DriveDictionary {
    /// The twin's built-in CiA 402 drive: the objects the driver uses and a few more, rated
    /// torque `rated_torque_mnm` (mN·m, as CiA 402 gives it), positions in increments,
    /// velocities in increments per second; like the EPOS4, no TPDO event timer.
    pub fn generic(rated_torque_mnm: u32) -> DriveDictionary {
        use ObjectAccess::{Const, ReadOnly as Ro, ReadWrite as Rw};
        let mut o = vec![
            described(0x1000, 0, ty::U32, Const, false, 0x0002_0192, false),
            described(0x1001, 0, ty::U8, Ro, false, 0, false),
            described(0x1003, 0, ty::U8, Rw, false, 0, false),
        ];
        for s in 1..=4 {
            o.push(described(0x1003, s, ty::U32, Ro, false, 0, false));
        }
        o.extend([
            described(0x1016, 0, ty::U8, Const, false, 1, false),
            described(0x1016, 1, ty::U32, Rw, false, 0, false),
            described(0x1017, 0, ty::U16, Rw, false, 0, false),
            described(0x1018, 0, ty::U8, Const, false, 4, false),
            described(0x1018, 1, ty::U32, Const, false, 0x0000_0F1D, false),
            described(0x1018, 2, ty::U32, Const, false, 0x0402_0001, false),
            described(0x1018, 3, ty::U32, Const, false, 0x0001_0000, false),
            described(0x1018, 4, ty::U32, Const, false, 0, true),
        ]);
        // PDO communication and mapping parameters: RPDO1, TPDO1, TPDO2 (CiA 301 defaults:
        // predefined COB-IDs, TPDOs disabled until mapped, asynchronous).
        for (comm, map, cob, invalid) in [
            (0x1400u16, 0x1600u16, 0x200, false),
            (0x1800, 0x1A00, 0x180, true),
            (0x1801, 0x1A01, 0x280, true),
        ] {
            let is_tpdo = comm >= 0x1800;
            o.push(described(
                comm,
                0,
                ty::U8,
                Const,
                false,
                if is_tpdo { 3 } else { 2 },
                false,
            ));
            let flag = if invalid { 0x8000_0000 } else { 0 };
            o.push(described(comm, 1, ty::U32, Rw, false, flag | cob, true));
            o.push(described(comm, 2, ty::U8, Rw, false, 0xFF, false));
            if is_tpdo {
                // Inhibit time (100 µs units) of event-driven TPDOs; no event timer (sub 5).
                o.push(described(comm, 3, ty::U16, Rw, false, 0, false));
            }
            o.push(described(map, 0, ty::U8, Rw, false, 0, false));
            for s in 1..=4 {
                o.push(described(map, s, ty::U32, Rw, false, 0, false));
            }
        }
        o.extend([
            described(0x603F, 0, ty::U16, Ro, true, 0, false),
            described(0x6007, 0, ty::I16, Rw, false, 1, false),
            described(0x6040, 0, ty::U16, Rw, true, 0, false),
            described(0x6041, 0, ty::U16, Ro, true, 0x0250, false),
            described(0x6060, 0, ty::I8, Rw, true, 0, false),
            described(0x6061, 0, ty::I8, Ro, true, 0, false),
            described(0x6064, 0, ty::I32, Ro, true, 0, false),
            described(0x606C, 0, ty::I32, Ro, true, 0, false),
            described(0x6071, 0, ty::I16, Rw, true, 0, false),
            described(0x6072, 0, ty::U16, Rw, true, 3000, false),
            described(
                0x6076,
                0,
                ty::U32,
                Rw,
                false,
                i128::from(rated_torque_mnm),
                false,
            ),
            described(0x6077, 0, ty::I16, Ro, true, 0, false),
            described(0x607E, 0, ty::U8, Rw, false, 0, false),
            described(0x6502, 0, ty::U32, Const, false, 0x0000_0380, false),
            // The analog input, at its CiA 401 place and at the EPOS4's (input 2 is unwired).
            described(0x6401, 0, ty::U8, Const, false, 1, false),
            described(0x6401, 1, ty::I16, Ro, true, 0, false),
            described(0x3160, 0, ty::U8, Const, false, 2, false),
            described(0x3160, 1, ty::I16, Ro, true, 0, false),
            described(0x3160, 2, ty::I16, Ro, true, 0, false),
        ]);
        o.sort_by_key(|d| (d.index, d.subindex));
        DriveDictionary {
            source: "generic CiA 402 profile".into(),
            objects: o,
            torque_unit_nm: 1e-3,
            counts_per_position_unit: 1.0,
            counts_per_s_per_velocity_unit: 1.0,
        }
    }

    /// The dictionary as an EDS (CiA 306): `[DeviceInfo]`, then every object, a record's
    /// header before its sub-indices; defaults with `$NODEID+` where they take the node id.
    /// The generic profile so written is a part any CANopen stack can load.
    pub fn to_eds(&self, product_name: &str) -> String {
        use std::fmt::Write;
        let mut out = String::new();
        let _ = write!(
            out,
            "[DeviceInfo]\nVendorName=VIDET\nProductName={product_name}\nVendorNumber=0\n\
             ProductNumber=0\nBaudRate_1000=1\nSimpleBootUpSlave=1\nNrOfRXPDO=1\nNrOfTXPDO=2\n\n"
        );
        let access = |a: ObjectAccess| match a {
            ObjectAccess::ReadOnly => "ro",
            ObjectAccess::WriteOnly => "wo",
            ObjectAccess::ReadWrite => "rw",
            ObjectAccess::Const => "const",
        };
        let entry = |out: &mut String, header: &str, o: &DescribedObject| {
            let _ = write!(out, "[{header}]\nParameterName={header}\nObjectType=0x7\n");
            if let Some(t) = o.data_type {
                let _ = writeln!(out, "DataType={t:#06x}");
            }
            let _ = writeln!(out, "AccessType={}", access(o.access));
            match (&o.text, o.default) {
                (Some(text), _) => {
                    let _ = writeln!(out, "DefaultValue={text}");
                }
                (None, Some(d)) if d.plus_node_id => {
                    let _ = writeln!(out, "DefaultValue=$NODEID+{:#x}", d.value);
                }
                (None, Some(d)) if d.value < 0 => {
                    let _ = writeln!(out, "DefaultValue={}", d.value);
                }
                (None, Some(d)) => {
                    let _ = writeln!(out, "DefaultValue={:#x}", d.value);
                }
                (None, None) => {}
            }
            let _ = writeln!(out, "PDOMapping={}\n", u8::from(o.pdo_mappable));
        };
        let mut i = 0;
        while i < self.objects.len() {
            let index = self.objects[i].index;
            let end = i + self.objects[i..]
                .iter()
                .take_while(|o| o.index == index)
                .count();
            let subs = &self.objects[i..end];
            if subs.len() == 1 && subs[0].subindex == 0 {
                entry(&mut out, &format!("{index:04X}"), &subs[0]);
            } else {
                let _ = write!(
                    out,
                    "[{index:04X}]\nParameterName={index:04X}\nObjectType=0x9\nSubNumber={}\n\n",
                    subs.len()
                );
                for o in subs {
                    entry(&mut out, &format!("{index:04X}sub{:X}", o.subindex), o);
                }
            }
            i = end;
        }
        out
    }

    /// The object at `index:subindex`.
    pub fn object(&self, index: u16, subindex: u8) -> Option<&DescribedObject> {
        self.objects
            .binary_search_by_key(&(index, subindex), |d| (d.index, d.subindex))
            .ok()
            .map(|i| &self.objects[i])
    }

    /// Whether any sub-index of `index` exists.
    pub fn has_index(&self, index: u16) -> bool {
        let at = self.objects.partition_point(|d| d.index < index);
        self.objects.get(at).is_some_and(|d| d.index == index)
    }

    /// The default of `index:subindex` on node `node_id`, if it has a numeric one.
    pub fn default_of(&self, index: u16, subindex: u8, node_id: u8) -> Option<i128> {
        self.object(index, subindex)?.default.map(|d| d.at(node_id))
    }

    /// The object dictionary of the drive of node `node_id`, every object with its default;
    /// objects whose type the dictionary cannot hold (a record's header without a type) are
    /// left out of it but still exist for [`DriveDictionary::check_sdo`].
    pub fn build(&self, node_id: u8) -> ObjectDictionary<OD_CAPACITY> {
        let mut od = ObjectDictionary::<OD_CAPACITY>::new();
        // The dictionary looks objects up in insertion order: the ones every SYNC reads and
        // writes go first, or a real drive's hundreds of objects would be searched each time.
        let hot = |d: &&DescribedObject| {
            HOT_OBJECTS.contains(&d.index)
                || is_mapping(d.index)
                || (0x1400..=0x1BFF).contains(&d.index)
        };
        let (first, rest): (Vec<&DescribedObject>, Vec<&DescribedObject>) =
            self.objects.iter().partition(hot);
        for d in first.into_iter().chain(rest) {
            let Some(value) = initial_value(d, node_id) else {
                continue;
            };
            let access = match d.access {
                ObjectAccess::ReadOnly => canopen_rs::AccessType::Ro,
                ObjectAccess::WriteOnly => canopen_rs::AccessType::Wo,
                ObjectAccess::ReadWrite => canopen_rs::AccessType::Rw,
                ObjectAccess::Const => canopen_rs::AccessType::Const,
            };
            // The capacity holds the largest shipped dictionary; beyond it, objects are left
            // out (and answered as absent by the server).
            let _ = od.insert(Address::new(d.index, d.subindex), Entry { value, access });
        }
        od
    }
}

/// The value an object starts with: its default in its data type (0 when it has none).
fn initial_value(d: &DescribedObject, node_id: u8) -> Option<Value> {
    let v = d.default.map_or(0, |x| x.at(node_id));
    Some(match d.data_type? {
        0x01 => Value::Boolean(v != 0),
        0x02 => Value::Integer8(v as i8),
        0x03 => Value::Integer16(v as i16),
        0x04 => Value::Integer32(v as i32),
        0x05 => Value::Unsigned8(v as u8),
        0x06 => Value::Unsigned16(v as u16),
        0x07 => Value::Unsigned32(v as u32),
        0x08 => Value::Real32(v as f32),
        0x11 => Value::Real64(v as f64),
        0x15 => Value::Integer64(v as i64),
        0x1B => Value::Unsigned64(v as u64),
        0x09 => {
            let text = d.text.as_deref().unwrap_or("");
            let cut = &text.as_bytes()[..text.len().min(canopen_rs::MAX_STRING_LEN)];
            Value::VisibleString(ByteString::from_bytes(cut).ok()?)
        }
        0x0A => Value::OctetString(ByteString::new()),
        0x0F => Value::Domain(ByteString::new()),
        _ => return None,
    })
}

/// Size in bytes of a fixed-size CiA 301 data type.
fn type_size(data_type: u16) -> Option<usize> {
    match data_type {
        0x01 | 0x02 | 0x05 => Some(1),
        0x03 | 0x06 => Some(2),
        0x04 | 0x07 | 0x08 => Some(4),
        0x11 | 0x15 | 0x1B => Some(8),
        _ => None,
    }
}

impl DriveDictionary {
    /// The CiA 301 abort a drive of this dictionary answers the SDO request `request` with,
    /// when the dictionary does not allow it; `None` when the request may be served. `od` is
    /// the drive's current dictionary (for the PDO state the mapping rules depend on).
    pub fn check_sdo(&self, request: &[u8], od: &ObjectDictionary<OD_CAPACITY>) -> Option<u32> {
        let d: &[u8; 8] = request.try_into().ok()?;
        let ccs = d[0] >> 5;
        // 1: initiate download, 2: initiate upload; segments carry no address.
        if ccs != 1 && ccs != 2 {
            return None;
        }
        let index = u16::from_le_bytes([d[1], d[2]]);
        let sub = d[3];
        if !self.has_index(index) {
            return Some(abort::NO_OBJECT);
        }
        let Some(object) = self.object(index, sub) else {
            return Some(abort::NO_SUBINDEX);
        };
        if ccs == 2 {
            return (object.access == ObjectAccess::WriteOnly).then_some(abort::WRITE_ONLY);
        }
        if matches!(object.access, ObjectAccess::ReadOnly | ObjectAccess::Const) {
            return Some(abort::READ_ONLY);
        }
        let expedited = d[0] & 0x02 != 0;
        let size_indicated = d[0] & 0x01 != 0;
        let length = match (expedited, size_indicated) {
            (true, true) => Some(4 - usize::from((d[0] >> 2) & 0x03)),
            (false, true) => Some(u32::from_le_bytes([d[4], d[5], d[6], d[7]]) as usize),
            _ => None,
        };
        if let (Some(n), Some(size)) = (length, object.data_type.and_then(type_size)) {
            if n != size {
                return Some(abort::LENGTH_MISMATCH);
            }
        }
        if !expedited {
            return None;
        }
        let value = u32::from_le_bytes([d[4], d[5], d[6], d[7]]);
        if is_mapping(index) {
            return self.check_mapping(index, sub, value, od);
        }
        if index == 0x6060 {
            return self.check_mode(value as u8 as i8);
        }
        None
    }

    /// CiA 301's rules for writing a PDO mapping: entries only while the PDO is invalid and
    /// the entry count is 0; each entry an existing, mappable object of the entry's length;
    /// a count whose entries fit in 64 bits.
    fn check_mapping(
        &self,
        index: u16,
        sub: u8,
        value: u32,
        od: &ObjectDictionary<OD_CAPACITY>,
    ) -> Option<u32> {
        // The communication parameter of this mapping: 0x1600 -> 0x1400, 0x1A00 -> 0x1800.
        let comm = index - 0x200;
        let valid = matches!(
            od.read(Address::new(comm, 1)),
            Ok(Value::Unsigned32(cob)) if cob & 0x8000_0000 == 0
        );
        let count = match od.read(Address::new(index, 0)) {
            Ok(Value::Unsigned8(n)) => n,
            _ => 0,
        };
        if valid || (sub >= 1 && count != 0) {
            return Some(abort::UNSUPPORTED_ACCESS);
        }
        if sub >= 1 {
            if value == 0 {
                return None;
            }
            let (mapped, mapped_sub, bits) =
                ((value >> 16) as u16, (value >> 8) as u8, value as u8);
            let fits = self.object(mapped, mapped_sub).is_some_and(|o| {
                o.pdo_mappable
                    && o.data_type
                        .and_then(type_size)
                        .is_some_and(|s| s * 8 == usize::from(bits))
            });
            return (!fits).then_some(abort::NOT_MAPPABLE);
        }
        let entries = value as u8;
        let mut bits = 0u32;
        for s in 1..=entries {
            let Ok(Value::Unsigned32(e)) = od.read(Address::new(index, s)) else {
                return Some(abort::NOT_MAPPABLE);
            };
            bits += e & 0xFF;
        }
        (bits > 64).then_some(abort::MAPPING_TOO_LONG)
    }

    /// A mode of operation the drive does not list in its supported drive modes (0x6502;
    /// modes 1..=10 are bits 0..=9) is an invalid value. A drive without 0x6502 takes any.
    fn check_mode(&self, mode: i8) -> Option<u32> {
        let supported = self.default_of(0x6502, 0, 0)?;
        if !(1..=10).contains(&mode) {
            return None;
        }
        (supported & (1 << (mode - 1)) == 0).then_some(abort::INVALID_VALUE)
    }
}

/// The objects a simulated drive reads or writes at every SYNC or frame.
const HOT_OBJECTS: [u16; 15] = [
    0x6040, 0x6041, 0x603F, 0x6060, 0x6061, 0x6064, 0x606C, 0x6071, 0x6076, 0x6077, 0x607E, 0x6401,
    0x3160, 0x1016, 0x1017,
];

/// Whether `index` is a PDO mapping parameter.
fn is_mapping(index: u16) -> bool {
    matches!(index, 0x1600..=0x17FF | 0x1A00..=0x1BFF)
}

/// The eight bytes of an SDO abort of `index:sub` with `code`.
pub fn abort_frame(index: u16, sub: u8, code: u32) -> [u8; 8] {
    let mut f = [0x80, 0, 0, sub, 0, 0, 0, 0];
    f[1..3].copy_from_slice(&index.to_le_bytes());
    f[4..].copy_from_slice(&code.to_le_bytes());
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn download(index: u16, sub: u8, value: u32, bytes: u8) -> [u8; 8] {
        let mut d = [0u8; 8];
        d[0] = 0x23 | ((4 - bytes) << 2);
        d[1..3].copy_from_slice(&index.to_le_bytes());
        d[3] = sub;
        d[4..].copy_from_slice(&value.to_le_bytes());
        d
    }

    #[test]
    fn the_generic_profile_answers_each_refusal_as_cia301_says() {
        let dict = DriveDictionary::generic(100);
        let od = dict.build(1);
        let check = |d: [u8; 8]| dict.check_sdo(&d, &od);
        assert_eq!(check(download(0x2000, 0, 0, 4)), Some(abort::NO_OBJECT));
        assert_eq!(check(download(0x1801, 5, 10, 2)), Some(abort::NO_SUBINDEX));
        assert_eq!(check(download(0x1000, 0, 1, 4)), Some(abort::READ_ONLY));
        assert_eq!(
            check(download(0x1017, 0, 10, 4)),
            Some(abort::LENGTH_MISMATCH)
        );
        assert_eq!(check(download(0x1017, 0, 10, 2)), None);
        // RPDO1 is valid by default: its mapping may not change.
        assert_eq!(
            check(download(0x1600, 1, 0x6040_0010, 4)),
            Some(abort::UNSUPPORTED_ACCESS)
        );
        // TPDO1 is invalid and unmapped: an entry of a mappable object of its length goes,
        // one of another length or of an object that cannot be mapped does not.
        assert_eq!(check(download(0x1A00, 1, 0x6064_0020, 4)), None);
        assert_eq!(
            check(download(0x1A00, 1, 0x6064_0010, 4)),
            Some(abort::NOT_MAPPABLE)
        );
        assert_eq!(
            check(download(0x1A00, 1, 0x6076_0020, 4)),
            Some(abort::NOT_MAPPABLE)
        );
        // Cyclic synchronous torque is supported, profile torque (4) is not.
        assert_eq!(check(download(0x6060, 0, 10, 1)), None);
        assert_eq!(check(download(0x6060, 0, 4, 1)), Some(abort::INVALID_VALUE));
        // Upload of an absent sub-index.
        let upload = [0x40, 0x18, 0x10, 0x09, 0, 0, 0, 0];
        assert_eq!(check(upload), Some(abort::NO_SUBINDEX));
    }

    #[test]
    fn node_relative_defaults_take_the_node_id() {
        let dict = DriveDictionary::generic(100);
        assert_eq!(dict.default_of(0x1800, 1, 5), Some(0x8000_0185));
        let od = dict.build(5);
        assert_eq!(
            od.read(Address::new(0x1400, 1)),
            Ok(Value::Unsigned32(0x205))
        );
        assert_eq!(od.read(Address::new(0x6076, 0)), Ok(Value::Unsigned32(100)));
    }
}
