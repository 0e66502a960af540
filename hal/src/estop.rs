//! The emergency-stop input.

use crate::ErrorType;

/// The emergency-stop button. Latched: once seen pressed it stays pressed until `reset`.
pub trait EStop: ErrorType {
    /// Whether the e-stop is (latched) pressed. **RT**.
    fn is_pressed(&mut self) -> Result<bool, Self::Error>;
    /// Clear the latch; fails (kind `Fault`) while the button is still held. **non-RT**.
    fn reset(&mut self) -> Result<(), Self::Error>;
}
