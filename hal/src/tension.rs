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

/// Conversion timing and resolution of one converter type, as configured: what the service's
/// tension-loop budget and the twin's simulated converters both go by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConverterModel {
    /// Conversions per second.
    pub sample_rate_sps: f64,
    /// Order of the digital filter (conversions to settle a step): 0 samples the input at the
    /// conversion instant (no filter).
    pub filter_order: u32,
    /// Newtons per count: the quantization step (0: none).
    pub newtons_per_count: f64,
}

impl ConverterModel {
    /// The conversion period, seconds.
    pub fn period_s(&self) -> f64 {
        1.0 / self.sample_rate_sps
    }

    /// The filter's group delay, seconds: half its span.
    pub fn group_delay_s(&self) -> f64 {
        f64::from(self.filter_order) * self.period_s() / 2.0
    }

    /// Time for a step at the input to be fully in the output, seconds.
    pub fn settling_s(&self) -> f64 {
        f64::from(self.filter_order.max(1)) * self.period_s()
    }
}
