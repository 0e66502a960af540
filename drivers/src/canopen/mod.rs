//! The CiA 301 pieces the drive driver needs on top of `canopen-rs` (which provides the SDO,
//! NMT, EMCY and PDO codecs): COB-ID classification, readable EMCY and SDO-abort texts and a
//! candump trace reader (the EDS/DCF reader is `videt-drive-description`'s).

pub mod cob;
pub mod codes;
pub mod host_trace;
pub mod objects;
pub mod trace;
