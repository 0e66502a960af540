//! The configured device as the service runs it: the wire count is a const generic chosen once
//! at start-up (`videtd` matches `rig.device` and calls one monomorphized service), never a
//! dispatch inside the control period.
//!
//! - [`RuntimeDevice`]: what the runtime needs of a device beyond its control step (how its
//!   geometry is recorded in the session log, whether the base-triangle calibration applies).
//!
//! What the service needs of its hardware beyond the HAL capabilities is the service's own
//! (`videt_service::service_hardware`).

use videt_control::{PlanarDevice, PolarDevice, Rig3, RigPlanar, Vec3, WireDevice};

use crate::WIREMAN_WIRES;

/// A device the service can run.
pub trait RuntimeDevice<const N: usize>: WireDevice<N> {
    /// The device's guide points as the session log records them, `[x, y, z]` metres, one per
    /// wire (the remaining slots zero).
    fn logged_guides_m(&self) -> [[f64; 3]; WIREMAN_WIRES];

    /// The device back from recorded guide points.
    fn from_logged_guides(guides_m: &[[f64; 3]; WIREMAN_WIRES]) -> Result<Self, String>;

    /// The device after an auto-initialization measured the base triangle (`None`: the
    /// procedure does not apply to this device).
    fn from_base_triangle(rig: Rig3) -> Option<Self>;
}

impl RuntimeDevice<WIREMAN_WIRES> for Rig3 {
    fn logged_guides_m(&self) -> [[f64; 3]; WIREMAN_WIRES] {
        let g = self.guides_m();
        core::array::from_fn(|i| [g[i].x, g[i].y, g[i].z])
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; WIREMAN_WIRES]) -> Result<Self, String> {
        Rig3::new(guides_m.map(|g| Vec3::new(g[0], g[1], g[2])))
            .map_err(|e| format!("recorded rig geometry: {e}"))
    }

    fn from_base_triangle(rig: Rig3) -> Option<Self> {
        Some(rig)
    }
}

impl RuntimeDevice<2> for PlanarDevice {
    fn logged_guides_m(&self) -> [[f64; 3]; WIREMAN_WIRES] {
        let [x0, x1] = self.rig().guides_x_m();
        [[x0, 0.0, 0.0], [x1, 0.0, 0.0], [0.0; 3]]
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; WIREMAN_WIRES]) -> Result<Self, String> {
        RigPlanar::new([guides_m[0][0], guides_m[1][0]])
            .map(PlanarDevice::new)
            .map_err(|e| format!("recorded planar geometry: {e}"))
    }

    fn from_base_triangle(_rig: Rig3) -> Option<Self> {
        None
    }
}

impl RuntimeDevice<1> for PolarDevice {
    fn logged_guides_m(&self) -> [[f64; 3]; WIREMAN_WIRES] {
        let g = self.guide_m();
        [[g.x, g.y, g.z], [0.0; 3], [0.0; 3]]
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; WIREMAN_WIRES]) -> Result<Self, String> {
        let g = guides_m[0];
        PolarDevice::new(Vec3::new(g[0], g[1], g[2]))
            .map_err(|e| format!("recorded one-wire geometry: {e}"))
    }

    fn from_base_triangle(_rig: Rig3) -> Option<Self> {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_device_comes_back_from_its_log() {
        let rig = Rig3::new([
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.3, 0.0),
        ])
        .unwrap();
        assert_eq!(
            Rig3::from_logged_guides(&rig.logged_guides_m()).unwrap(),
            rig
        );
        let planar = PlanarDevice::paper_prototype();
        assert_eq!(
            PlanarDevice::from_logged_guides(&planar.logged_guides_m()).unwrap(),
            planar
        );
        let polar = PolarDevice::new(Vec3::new(0.1, 0.2, 0.0)).unwrap();
        assert_eq!(
            PolarDevice::from_logged_guides(&polar.logged_guides_m()).unwrap(),
            polar
        );
        assert!(PlanarDevice::from_logged_guides(&[[0.1, 0.0, 0.0]; 3]).is_err());
        assert!(PlanarDevice::from_base_triangle(rig).is_none());
        assert_eq!(Rig3::from_base_triangle(rig), Some(rig));
    }
}
