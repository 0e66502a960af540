//! Strain-gauge ADCs for the wire-tension sensors, generic over embedded-hal 1.0 traits:
//! [`hx711::Hx711`] (bit-banged clock/data) and [`ads1220::Ads1220`] (SPI precision ADC), or
//! the load-cell amplifier wired into each wire drive's analog input
//! ([`drive_input::DriveInputAdc`], read from the drives' TPDO2); the two-point tension
//! [`calibration`], the set of one sensor per wire implementing `videt_hal::TensionSensors<N>`
//! for any wire count ([`tension_set`]), and their Linux devices ([`linux`]).
//!
//! Reads never block the control loop: a driver answers `nb::Error::WouldBlock` while no new
//! conversion is ready, and the set then keeps the last sample (failing only once a sample is
//! older than its staleness limit).

pub mod ads1220;
pub mod calibration;
pub mod drive_input;
pub mod hx711;
#[cfg(target_os = "linux")]
pub mod linux;
pub mod tension_set;

/// An ADC delivering raw signed conversions without blocking.
pub trait RawAdc {
    /// The driver's error.
    type Error: core::fmt::Debug;
    /// The newest conversion if one is ready (`WouldBlock` otherwise). **RT**.
    fn read_raw(&mut self) -> nb::Result<i32, Self::Error>;
}
