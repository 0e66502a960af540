//! # videt-drivers — the real devices of VIDET
//!
//! - [`can`]: the CAN seam (`embedded-can` + receive with timeout) and the SocketCAN backend;
//! - [`canopen`]: CiA 301 helpers on `canopen-rs` (COB-IDs, EMCY/SDO texts, candump and EDS
//!   readers; the EDS/DCF reader is `videt-drive-description`'s);
//! - [`cia402`]: CiA 402 wire drives in cyclic synchronous torque mode (`WireDrives`);
//! - [`adc`]: HX711 and ADS1220 strain-gauge ADCs or the drives' analog inputs, tension
//!   calibration (`TensionSensors`);
//! - [`angle`]: AS5048A absolute magnetic encoders, the one-wire device's azimuth and elevation
//!   sensors (`AngleSensors`);
//! - [`gpio`]: the e-stop input (`EStop`) and the vibrotactor outputs (`Vibrotactors`);
//! - [`camera`]: image-file stereo source and, with the `v4l` feature, V4L2 stereo capture
//!   (`StereoCamera`).
//!
//! Every driver is generic over `embedded-hal` / `embedded-can` traits, so the same code runs
//! on Linux (SocketCAN, spidev, gpio-cdev) and against mocks or the twin in tests.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod adc;
pub mod angle;
pub mod camera;
pub mod can;
pub mod canopen;
pub mod cia402;
pub mod gpio;
