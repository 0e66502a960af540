//! Readable texts for EMCY error codes (CiA 301 Table 21, CiA 402 §8.2) and SDO abort codes
//! (CiA 301 Table 22). Static strings: usable on the real-time path.

/// A short description of an EMCY / 0x603F error code. Specific codes first, then the class
/// of the code's high byte.
pub fn emcy_description(code: u16) -> &'static str {
    match code {
        0x0000 => "error reset or no error",
        0x1000 => "generic error",
        0x2310 => "continuous over-current",
        0x2320 => "short circuit at outputs",
        0x2330 => "earth leakage",
        0x3110 => "mains over-voltage",
        0x3120 => "mains under-voltage",
        0x3210 => "DC link over-voltage",
        0x3220 => "DC link under-voltage",
        0x4210 => "excess temperature device",
        0x4310 => "excess temperature drive",
        0x5113 => "supply low voltage",
        0x5530 => "data storage (EEPROM) error",
        0x6010 => "software reset (watchdog)",
        0x6320 => "parameter error",
        0x7121 => "motor blocked",
        0x7300 => "sensor error",
        0x7305 => "incremental sensor 1 fault (encoder)",
        0x7500 => "communication error",
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8150 => "CAN-ID collision",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8250 => "RPDO timeout",
        0x8400 => "velocity speed controller (following error)",
        0x8611 => "following error",
        0x8612 => "reference limit",
        0x9000 => "external error",
        0xFF00..=0xFFFF => "device-specific error",
        _ => emcy_class_description(code),
    }
}

fn emcy_class_description(code: u16) -> &'static str {
    match code >> 8 {
        0x10 => "generic error",
        0x20..=0x2F => "current error",
        0x30..=0x3F => "voltage error",
        0x40..=0x4F => "temperature error",
        0x50..=0x5F => "device hardware error",
        0x60..=0x6F => "device software error",
        0x70..=0x7F => "additional modules error",
        0x80..=0x8F => "monitoring / communication error",
        0x90..=0x9F => "external error",
        0xF0 => "additional functions error",
        _ => "unknown error code",
    }
}

/// The meaning of an SDO abort code.
pub fn sdo_abort_description(code: u32) -> &'static str {
    match code {
        0x0503_0000 => "toggle bit not alternated",
        0x0504_0000 => "SDO protocol timed out",
        0x0504_0001 => "client/server command specifier not valid or unknown",
        0x0504_0002 => "invalid block size (block transfer)",
        0x0504_0003 => "invalid sequence number (block transfer)",
        0x0504_0004 => "CRC error (block transfer)",
        0x0504_0005 => "out of memory",
        0x0601_0000 => "unsupported access to an object",
        0x0601_0001 => "attempt to read a write-only object",
        0x0601_0002 => "attempt to write a read-only object",
        0x0602_0000 => "object does not exist in the object dictionary",
        0x0604_0041 => "object cannot be mapped to the PDO",
        0x0604_0042 => "mapped objects would exceed the PDO length",
        0x0604_0043 => "general parameter incompatibility",
        0x0604_0047 => "general internal incompatibility in the device",
        0x0606_0000 => "access failed due to a hardware error",
        0x0607_0010 => "data type does not match, length of service parameter does not match",
        0x0607_0012 => "data type does not match, length of service parameter too high",
        0x0607_0013 => "data type does not match, length of service parameter too low",
        0x0609_0011 => "sub-index does not exist",
        0x0609_0030 => "invalid value for parameter",
        0x0609_0031 => "value of parameter written too high",
        0x0609_0032 => "value of parameter written too low",
        0x0609_0036 => "maximum value is less than minimum value",
        0x060A_0023 => "resource not available: SDO connection",
        0x0800_0000 => "general error",
        0x0800_0020 => "data cannot be transferred or stored to the application",
        0x0800_0021 => "data cannot be transferred because of local control",
        0x0800_0022 => "data cannot be transferred because of the present device state",
        0x0800_0023 => {
            "object dictionary dynamic generation failed or no object dictionary is \
                        present"
        }
        0x0800_0024 => "no data available",
        _ => "unknown SDO abort code",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn common_codes_have_specific_texts_and_others_fall_back_to_their_class() {
        assert_eq!(emcy_description(0x8130), "life guard or heartbeat error");
        assert_eq!(emcy_description(0x2310), "continuous over-current");
        assert_eq!(emcy_description(0x2399), "current error");
        assert_eq!(emcy_description(0x4299), "temperature error");
        assert_eq!(emcy_description(0xFF01), "device-specific error");
        assert_eq!(emcy_description(0xA000), "unknown error code");
        assert_eq!(
            sdo_abort_description(0x0602_0000),
            "object does not exist in the object dictionary"
        );
        assert_eq!(sdo_abort_description(0x1234_5678), "unknown SDO abort code");
    }

    /// Every abort code of CiA 301 (version 4.2, table 22) has its own text
    /// (`scripts/canopen-peer/test_abort_codes.py` checks the table against python-canopen's).
    #[test]
    fn every_cia301_abort_code_is_named() {
        const CIA301: [u32; 31] = [
            0x0503_0000,
            0x0504_0000,
            0x0504_0001,
            0x0504_0002,
            0x0504_0003,
            0x0504_0004,
            0x0504_0005,
            0x0601_0000,
            0x0601_0001,
            0x0601_0002,
            0x0602_0000,
            0x0604_0041,
            0x0604_0042,
            0x0604_0043,
            0x0604_0047,
            0x0606_0000,
            0x0607_0010,
            0x0607_0012,
            0x0607_0013,
            0x0609_0011,
            0x0609_0030,
            0x0609_0031,
            0x0609_0032,
            0x0609_0036,
            0x060A_0023,
            0x0800_0000,
            0x0800_0020,
            0x0800_0021,
            0x0800_0022,
            0x0800_0023,
            0x0800_0024,
        ];
        let texts: std::collections::BTreeSet<_> =
            CIA301.iter().map(|&c| sdo_abort_description(c)).collect();
        assert!(!texts.contains("unknown SDO abort code"), "{texts:?}");
        assert_eq!(texts.len(), CIA301.len(), "two codes share a text");
        assert_eq!(
            sdo_abort_description(0x060A_0023),
            "resource not available: SDO connection"
        );
    }
}
