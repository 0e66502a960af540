//! Strain-gauge wire-tension sensors.

use crate::{ErrorType, WIRES};

/// The wire-tension sensors, one per wire.
pub trait TensionSensors: ErrorType {
    /// The latest calibrated tension of each wire, newtons. **RT**: returns the last converted
    /// sample and never waits for a conversion; an error when a sample is stale past the
    /// sensor's own timeout.
    fn read_tensions(&mut self, out_n: &mut [f64; WIRES]) -> Result<(), Self::Error>;
}
