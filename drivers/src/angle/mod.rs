//! The one-wire device's two passive angle sensors (azimuth and elevation of the wire at its
//! guide, paper section 4.4, eq. 7): ams AS5048A absolute magnetic rotary encoders on SPI.
//!
//! Why this part: an absolute encoder knows its angle from the first read after power-up and
//! after any lost frame, where a quadrature encoder would need homing every start and again
//! after each missed count; the passive axes have no motor to home them with. Its 14 bits
//! resolve 2π/16384 rad (0.022°), about 0.2 mm sideways at 0.5 m of wire, finer than the hand
//! can hold still. It speaks SPI like the tension converters, so on Linux it takes the same
//! non-allocating spidev path ([`crate::adc::linux::RtSpidev`]).
//!
//! - [`as5048a`]: one encoder: 16-bit frames with even parity and the error flag, the pipelined
//!   angle read, the error register and the diagnostics (magnetic field) register;
//! - [`calibration`]: zero offset and sense of each axis, counts to radians in `(-pi, pi]`;
//! - [`pair`]: the azimuth and elevation encoders as the HAL's
//!   [`AngleSensors`](videt_hal::AngleSensors), with an error naming the sensor that failed;
//! - [`linux`]: the pair on two spidev devices.
//!
//! The read is pipelined: an AS5048A answers a command in the frame after it, so every read
//! sends "read ANGLE" and receives the answer to the previous read's command. One frame per
//! sensor per control period; the angle returned was latched when the previous frame ended, one
//! control period earlier (1 ms at 1 kHz).

pub mod as5048a;
pub mod calibration;
#[cfg(target_os = "linux")]
pub mod linux;
pub mod pair;

pub use as5048a::{As5048a, As5048aError, Diagnostics, ErrorRegister};
pub use calibration::{Calibration, Sense, COUNTS_PER_TURN, RAD_PER_COUNT};
pub use pair::{AngleError, AngleSensorPair};
