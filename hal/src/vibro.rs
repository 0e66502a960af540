//! Vibrotactors on three fingertips (colour rendering).

use crate::{ErrorType, VIBROTACTORS};

/// Three on/off vibrotactor outputs; the caller produces the waveform (e.g. 75 Hz, duty by
/// level) by switching them. **RT-safe**: each call is a GPIO write.
pub trait Vibrotactors: ErrorType {
    /// Set every output at once (`true` = on).
    fn set_outputs(&mut self, on: &[bool; VIBROTACTORS]) -> Result<(), Self::Error>;
}
