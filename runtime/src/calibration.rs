//! The calibration a control cycle starts with: the rig and the encoder zeros from a valid
//! calibration file, or the reason there is none, in which case the safety supervisor holds
//! every wire at minimum tension (`NotCalibrated`) and no force is rendered.

use std::path::Path;

use videt_config::calibration::Calibration;
use videt_config::Config;
use videt_control::Rig3;

use crate::cycle::WireZero;

/// The calibration state the control cycle starts with.
#[derive(Debug, Clone)]
pub struct CalibrationState {
    /// The rig to control (the calibration's when valid; else the configured one, unused for
    /// rendering).
    pub rig: Rig3,
    /// Encoder zeros.
    pub wire_zero: WireZero,
    /// Whether forces may be rendered.
    pub calibrated: bool,
    /// Why not, when not.
    pub reason: Option<String>,
    /// The calibration, when valid.
    pub calibration: Option<Calibration>,
}

/// The state from a calibration (checked against the configured transmission).
pub fn from_calibration(config: &Config, c: &Calibration) -> Result<CalibrationState, String> {
    let mpc = crate::setup::transmission(config).metres_per_count();
    if (c.metres_per_count - mpc).abs() > 1e-6 * mpc {
        return Err(format!(
            "it was measured with {} m per encoder count, the configuration gives {mpc}: run `videt init`",
            c.metres_per_count
        ));
    }
    let rig = rig_from_sides(&c.sides_m)?;
    Ok(CalibrationState {
        rig,
        wire_zero: WireZero {
            length_at_zero_m: c.length_at_zero_m(),
        },
        calibrated: true,
        reason: None,
        calibration: Some(c.clone()),
    })
}

/// Load the calibration file; when it is missing, corrupt or inconsistent, say why and fall
/// back to the configured rig with forces off.
pub fn load(config: &Config, path: &Path) -> Result<CalibrationState, String> {
    let not_calibrated = |reason: String| -> Result<CalibrationState, String> {
        // A configuration whose guides make no rig is refused on load; the paper's frame
        // stands in (unused for rendering: forces are off).
        let rig = crate::setup::rig(config)
            .or_else(|_| Rig3::from_sides(0.37, 0.35, 0.35))
            .map_err(|e| format!("no rig to hold the wires with: {e}"))?;
        Ok(CalibrationState {
            rig,
            wire_zero: WireZero::default(),
            calibrated: false,
            reason: Some(reason),
            calibration: None,
        })
    };
    match Calibration::load(path) {
        Ok(c) => match from_calibration(config, &c) {
            Ok(s) => Ok(s),
            Err(reason) => not_calibrated(format!("{}: {reason}", path.display())),
        },
        Err(e) => not_calibrated(e.to_string()),
    }
}

/// The control cycle's rig for measured base-triangle sides, metres.
pub fn rig_from_sides(sides_m: &[f64; 3]) -> Result<Rig3, String> {
    Rig3::from_sides(sides_m[0], sides_m[1], sides_m[2])
        .map_err(|e| format!("its sides do not make a rig: {e}"))
}
