//! The e-stop and vibrotactors on Linux GPIO character devices (`/dev/gpiochipN`), through
//! linux-embedded-hal's `CdevPin` (pure Rust, no system library).

use gpio_cdev::{Chip, LineRequestFlags};
pub use linux_embedded_hal::CdevPin;
use videt_hal::VIBROTACTORS;

use super::estop::EStopInput;
use super::vibro::VibrotactorOutputs;

/// A GPIO line that could not be opened.
#[derive(Debug, thiserror::Error)]
#[error("GPIO {chip} line {line} ({role}): {source}")]
pub struct OpenError {
    /// Chip device path.
    pub chip: String,
    /// Line offset.
    pub line: u32,
    /// What the line is for.
    pub role: &'static str,
    /// The underlying error.
    #[source]
    pub source: gpio_cdev::errors::Error,
}

/// Request `line` of `chip_path` as an input, or an output set low, labelled "videt".
pub(crate) fn open_line(
    chip_path: &str,
    line: u32,
    role: &'static str,
    output: bool,
) -> Result<CdevPin, OpenError> {
    let err = |source| OpenError {
        chip: chip_path.to_string(),
        line,
        role,
        source,
    };
    let mut chip = Chip::new(chip_path).map_err(err)?;
    let flags = if output {
        LineRequestFlags::OUTPUT
    } else {
        LineRequestFlags::INPUT
    };
    let handle = chip
        .get_line(line)
        .and_then(|l| l.request(flags, 0, "videt"))
        .map_err(err)?;
    CdevPin::new(handle).map_err(err)
}

/// The e-stop on `line` of `chip_path`, pressed at the line's low level (high with
/// `pressed_high`), debounced over `debounce_samples` reads.
pub fn estop(
    chip_path: &str,
    line: u32,
    debounce_samples: u8,
    pressed_high: bool,
) -> Result<EStopInput<CdevPin>, OpenError> {
    let input = EStopInput::new(
        open_line(chip_path, line, "e-stop", false)?,
        debounce_samples,
    );
    Ok(if pressed_high {
        input.pressed_when_high()
    } else {
        input
    })
}

/// The three vibrotactors on `lines` of `chip_path`, switched off.
pub fn vibrotactors(
    chip_path: &str,
    lines: [u32; VIBROTACTORS],
) -> Result<VibrotactorOutputs<CdevPin>, Box<dyn std::error::Error + Send + Sync>> {
    let pins = [
        open_line(chip_path, lines[0], "vibrotactor 0", true)?,
        open_line(chip_path, lines[1], "vibrotactor 1", true)?,
        open_line(chip_path, lines[2], "vibrotactor 2", true)?,
    ];
    Ok(VibrotactorOutputs::new(pins)?)
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_missing_chip_is_a_clear_error() {
        let Err(e) = super::estop("/dev/no-such-gpiochip", 4, 3, false) else {
            panic!("opened a missing chip");
        };
        let text = e.to_string();
        assert!(
            text.contains("/dev/no-such-gpiochip line 4 (e-stop)"),
            "{text}"
        );
    }
}
