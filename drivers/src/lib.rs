//! # videt-drivers — the real devices of VIDET
//!
//! - [`can`]: the CAN seam (`embedded-can` + receive with timeout) and the SocketCAN backend;
//! - [`canopen`]: CiA 301 helpers on `canopen-rs` (COB-IDs, EMCY/SDO texts, candump and EDS
//!   readers);
//! - [`cia402`]: CiA 402 wire drives in cyclic synchronous torque mode (`WireDrives`);
//!
//! Every driver is generic over `embedded-hal` / `embedded-can` traits, so the same code runs
//! on Linux (SocketCAN, spidev, gpio-cdev) and against mocks or the twin in tests.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod adc;
pub mod can;
pub mod canopen;
pub mod cia402;
pub mod gpio;
