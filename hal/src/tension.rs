//! Strain-gauge wire-tension sensors.

use crate::ErrorType;

/// The wire-tension sensors, one per wire of an `N`-wire device.
pub trait TensionSensors<const N: usize>: ErrorType {
    /// The latest calibrated tension of each wire, newtons. **RT**: returns the last converted
    /// sample and never waits for a conversion; an error when a sample is stale past the
    /// sensor's own timeout.
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), Self::Error>;

    /// As [`read_tensions`](Self::read_tensions), and which wires' samples are new since the
    /// previous read: a converter slower than the control rate repeats its last conversion in
    /// between. **RT**. The default, for sensors that cannot tell, calls every sample new.
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], Self::Error> {
        self.read_tensions(out_n).map(|()| [true; N])
    }
}
