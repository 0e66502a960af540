//! The analysis request: a rig and the thimble's position in it, and the analysed workspace the
//! position must lie in (in front of the guide plane, wires not too long, not singular).

use nalgebra::Vector2;
use videt_control::{Rig3, RigPlanar, Vec3};

/// Smallest distance of the analysed point in front of the guide plane, metres.
pub const MIN_HEIGHT_M: f64 = 0.01;
/// Longest wire of the analysed workspace, metres.
pub const MAX_WIRE_LENGTH_M: f64 = 1.5;

/// A validated analysis request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// Planar two-wire device at `[x, z]`.
    Planar {
        /// The rig.
        rig: RigPlanar,
        /// Position `[x, z]`, metres.
        at_m: Vector2<f64>,
    },
    /// Three-wire device.
    Spatial {
        /// The rig.
        rig: Rig3,
        /// Position, metres.
        at_m: Vec3,
    },
}

/// Why a point is outside the analysed workspace, or `Ok`.
pub fn check_planar_point(rig: &RigPlanar, at: &Vector2<f64>) -> Result<(), String> {
    check_point(at.y, &rig.inverse(at), rig.wire_map(at).is_some())
}

/// Why a point is outside the analysed workspace, or `Ok`.
pub fn check_spatial_point(rig: &Rig3, at: &Vec3) -> Result<(), String> {
    check_point(at.z, &rig.inverse(at), rig.wire_map(at).is_some())
}

fn check_point(height_m: f64, lengths_m: &[f64], regular: bool) -> Result<(), String> {
    if height_m < MIN_HEIGHT_M {
        return Err(format!(
            "the thimble must be in front of the guide plane: z = {height_m} m, need z >= {MIN_HEIGHT_M} m"
        ));
    }
    if let Some(l) = lengths_m.iter().find(|&&l| l > MAX_WIRE_LENGTH_M) {
        return Err(format!(
            "outside the workspace: a wire would be {l:.3} m long, at most {MAX_WIRE_LENGTH_M} m"
        ));
    }
    if !regular {
        return Err("the wires are (nearly) aligned there: singular point".into());
    }
    Ok(())
}
