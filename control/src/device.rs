//! A wire device as the control step sees it: sensed wire lengths (and passive angles) in, the
//! thimble's position and velocity out; a desired force in, tension set-points and the force
//! they make out. The wire count `N` is a const generic: each device is its own monomorphized
//! step, with no dynamic dispatch and no allocation in the period.
//!
//! The devices of the paper, and one beyond it:
//! - [`Rig3`]: the wearable WireMan, three wires from guides in the `z = 0` plane (eqs. 1-6);
//! - [`PlanarDevice`]: the planar two-wire prototype, the thimble confined to the x-z plane;
//! - [`PolarDevice`]: one actuated wire and two passive angle sensors (eq. 7);
//! - [`crate::spidar::Rig4`]: four wires from the corners of a frame around the workspace, which
//!   can make a force in every direction (tensions by the exact quadratic programme).
//!
//! Positions, velocities and forces are 3-vectors in the paper's frame for every device; a
//! device that spans fewer directions renders the part of the force it can make.

use nalgebra::SVector;

use crate::distribution::{clamp_tension, project, Distribution, ForceLimits};
use crate::field::{field_force, free_space_force, ForceField};
use crate::kinematics::{ForwardSolution, Rig3};
use crate::planar::{RigPlanar, Vec2};
use crate::polar::{
    one_wire_distribute, polar_forward, polar_inverse, polar_jacobian, PolarCoordinates,
};
use crate::wire_device::unit_and_length;
pub use crate::wire_device::{
    DeviceForces, DeviceKind, ForceSettings, Sensed, WireDevice, WireTensions,
};
use crate::wire_map::WireMap;
use crate::Vec3;

/// Field, target and projection on a device whose wires span its force space (`N` wires in
/// `N` dimensions).
fn square_forces<const N: usize>(
    map: &WireMap<N>,
    desired_n: &SVector<f64, N>,
    field_direction: SVector<f64, N>,
    in_contact: bool,
    scale: f64,
    settings: &ForceSettings,
) -> (SVector<f64, N>, SVector<f64, N>, Distribution<N>) {
    let field = ForceField {
        magnitude_n: settings.field.magnitude_n,
        direction: field_direction,
    };
    let f = field_force(settings.algorithm, &field, map);
    let mut field_n = if f == SVector::<f64, N>::zeros() && settings.free_space_field_n > 0.0 {
        let pull = free_space_force(settings.free_space_field_n, settings.limits.t_min_n, map);
        pull * free_space_pull_share(in_contact, desired_n.norm(), pull.norm())
    } else {
        f
    };
    field_n *= scale;
    let target = desired_n + field_n;
    let distribution = project(
        map,
        &target,
        settings.algorithm.projection(),
        &settings.limits,
    );
    (field_n, target, distribution)
}

/// How much of the free-space pull (`pull_n` newtons) stays with a contact force of
/// `desired_n` newtons: all of it out of contact, and in contact `1 - |f_e| / |pull|` down to
/// none, so a touch starts from the force felt just before it instead of dropping the pull in
/// one period.
pub fn free_space_pull_share(in_contact: bool, desired_n: f64, pull_n: f64) -> f64 {
    if !in_contact {
        return 1.0;
    }
    if pull_n.is_nan() || pull_n <= 1e-12 {
        return 0.0;
    }
    let share = 1.0 - desired_n / pull_n;
    if share.is_finite() {
        share.clamp(0.0, 1.0)
    } else {
        0.0
    }
}

impl WireDevice<3> for Rig3 {
    const KIND: DeviceKind = DeviceKind::Wireman3;

    fn forward(&self, sensed: &Sensed<3>) -> ForwardSolution {
        Rig3::forward(self, &sensed.lengths_m)
    }

    fn velocity(&self, position_m: &Vec3, sensed: &Sensed<3>) -> Option<Vec3> {
        self.velocity_from_rates(position_m, &sensed.length_rates_m_s)
    }

    fn inverse(&self, position_m: &Vec3) -> [f64; 3] {
        Rig3::inverse(self, position_m)
    }

    fn pull_direction(&self, position_m: &Vec3, wire: usize) -> Vec3 {
        -self.wire_from_guide(position_m, wire).0
    }

    fn wire_from_guide(&self, position_m: &Vec3, wire: usize) -> (Vec3, f64) {
        unit_and_length(position_m - self.guides_m()[wire])
    }

    fn force_of(&self, position_m: &Vec3, tensions_n: &[f64; 3]) -> Vec3 {
        self.force_matrix(position_m) * Vec3::from(*tensions_n)
    }

    fn forces(
        &self,
        position_m: &Vec3,
        desired_n: &Vec3,
        in_contact: bool,
        scale: f64,
        settings: &ForceSettings,
    ) -> Option<DeviceForces<3>> {
        let map = self.wire_map(position_m)?;
        let (field, target, d) = square_forces(
            &map,
            desired_n,
            settings.field.direction,
            in_contact,
            scale,
            settings,
        );
        Some(DeviceForces {
            field_force_n: field,
            target_force_n: target,
            tensions: WireTensions {
                tensions_n: d.tensions_n,
                rendered_n: d.rendered_n,
                saturated: d.saturated,
                projected: d.projected,
            },
        })
    }
}

/// The planar two-wire prototype as a device: the thimble at `[x, 0, z]`, guides on the x axis.
/// Forces outside the x-z plane are not rendered (the wires cannot make them; the prototype's
/// linkage holds the thimble in the plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarDevice {
    rig: RigPlanar,
}

impl PlanarDevice {
    /// The device of a planar rig.
    pub fn new(rig: RigPlanar) -> PlanarDevice {
        PlanarDevice { rig }
    }

    /// The paper's prototype: guides at `x = 0` and `x = 0.52` m.
    pub fn paper_prototype() -> PlanarDevice {
        PlanarDevice::new(RigPlanar::paper_prototype())
    }

    /// The planar rig.
    pub fn rig(&self) -> &RigPlanar {
        &self.rig
    }

    /// The guide points in the paper's 3D frame.
    pub fn guides_m(&self) -> [Vec3; 2] {
        let [x0, x1] = self.rig.guides_x_m();
        [Vec3::new(x0, 0.0, 0.0), Vec3::new(x1, 0.0, 0.0)]
    }
}

fn in_plane(v: &Vec3) -> Vec2 {
    Vec2::new(v.x, v.z)
}

fn from_plane(v: &Vec2) -> Vec3 {
    Vec3::new(v.x, 0.0, v.y)
}

impl WireDevice<2> for PlanarDevice {
    const KIND: DeviceKind = DeviceKind::Planar2;

    fn forward(&self, sensed: &Sensed<2>) -> ForwardSolution {
        let f = self.rig.forward(&sensed.lengths_m);
        ForwardSolution {
            position_m: from_plane(&f.position_m),
            clamped: f.clamped,
        }
    }

    fn velocity(&self, position_m: &Vec3, sensed: &Sensed<2>) -> Option<Vec3> {
        self.rig
            .velocity_from_rates(&in_plane(position_m), &sensed.length_rates_m_s)
            .map(|v| from_plane(&v))
    }

    fn inverse(&self, position_m: &Vec3) -> [f64; 2] {
        self.rig.inverse(&in_plane(position_m))
    }

    fn constrain(&self, position_m: &Vec3) -> Vec3 {
        Vec3::new(position_m.x, 0.0, position_m.z)
    }

    fn pull_direction(&self, position_m: &Vec3, wire: usize) -> Vec3 {
        let d = self.rig.wire_directions(&in_plane(position_m));
        from_plane(&-d.column(wire).into_owned())
    }

    fn wire_from_guide(&self, position_m: &Vec3, wire: usize) -> (Vec3, f64) {
        let g = self.rig.guides_x_m()[wire];
        unit_and_length(Vec3::new(position_m.x - g, 0.0, position_m.z))
    }

    fn forces(
        &self,
        position_m: &Vec3,
        desired_n: &Vec3,
        in_contact: bool,
        scale: f64,
        settings: &ForceSettings,
    ) -> Option<DeviceForces<2>> {
        let map = self.rig.wire_map(&in_plane(position_m))?;
        let (field, target, d) = square_forces(
            &map,
            &in_plane(desired_n),
            in_plane(&settings.field.direction),
            in_contact,
            scale,
            settings,
        );
        Some(DeviceForces {
            field_force_n: from_plane(&field),
            target_force_n: from_plane(&target),
            tensions: WireTensions {
                tensions_n: d.tensions_n,
                rendered_n: from_plane(&d.rendered_n),
                saturated: d.saturated,
                projected: d.projected,
            },
        })
    }
}

/// The one-wire device: a wire from a guide point, its direction measured by two passive angle
/// sensors (azimuth `alpha` about the guide's z axis from +x, elevation `beta` from the x-y
/// plane), eq. 7 about the guide. The only force it makes is a pull towards the guide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarDevice {
    guide_m: Vec3,
}

/// Why a one-wire device geometry was rejected.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PolarError;

impl core::fmt::Display for PolarError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("the guide point's coordinates must be finite")
    }
}

impl PolarDevice {
    /// A device whose wire leaves the guide at `guide_m`.
    pub fn new(guide_m: Vec3) -> Result<PolarDevice, PolarError> {
        if guide_m.iter().all(|c| c.is_finite()) {
            Ok(PolarDevice { guide_m })
        } else {
            Err(PolarError)
        }
    }

    /// The paper's Fig. 11: the guide at the origin.
    pub fn at_origin() -> PolarDevice {
        PolarDevice {
            guide_m: Vec3::zeros(),
        }
    }

    /// The guide point, metres.
    pub fn guide_m(&self) -> Vec3 {
        self.guide_m
    }

    fn coordinates(&self, sensed: &Sensed<1>) -> PolarCoordinates {
        PolarCoordinates {
            length_m: sensed.lengths_m[0],
            azimuth_rad: sensed.angles_rad[0],
            elevation_rad: sensed.angles_rad[1],
        }
    }
}

impl WireDevice<1> for PolarDevice {
    const KIND: DeviceKind = DeviceKind::Polar1;

    fn forward(&self, sensed: &Sensed<1>) -> ForwardSolution {
        let c = self.coordinates(sensed);
        let clamped = c.length_m.is_nan() || c.length_m < 0.0;
        let c = PolarCoordinates {
            length_m: if clamped { 0.0 } else { c.length_m },
            ..c
        };
        let p = polar_forward(&c) + self.guide_m;
        if p.iter().all(|v| v.is_finite()) {
            ForwardSolution {
                position_m: p,
                clamped,
            }
        } else {
            ForwardSolution {
                position_m: self.guide_m,
                clamped: true,
            }
        }
    }

    fn velocity(&self, _position_m: &Vec3, sensed: &Sensed<1>) -> Option<Vec3> {
        let j = polar_jacobian(&self.coordinates(sensed));
        let v = j * Vec3::new(
            sensed.length_rates_m_s[0],
            sensed.angle_rates_rad_s[0],
            sensed.angle_rates_rad_s[1],
        );
        v.iter().all(|c| c.is_finite()).then_some(v)
    }

    fn inverse(&self, position_m: &Vec3) -> [f64; 1] {
        [(position_m - self.guide_m).norm()]
    }

    fn passive_angles(&self, position_m: &Vec3) -> [f64; 2] {
        let c = polar_inverse(&(position_m - self.guide_m));
        [c.azimuth_rad, c.elevation_rad]
    }

    fn pull_direction(&self, position_m: &Vec3, _wire: usize) -> Vec3 {
        let d = position_m - self.guide_m;
        let l = d.norm();
        if l > 1e-12 && l.is_finite() {
            -d / l
        } else {
            -Vec3::z()
        }
    }

    fn wire_from_guide(&self, position_m: &Vec3, _wire: usize) -> (Vec3, f64) {
        unit_and_length(position_m - self.guide_m)
    }

    fn forces(
        &self,
        position_m: &Vec3,
        desired_n: &Vec3,
        in_contact: bool,
        scale: f64,
        settings: &ForceSettings,
    ) -> Option<DeviceForces<1>> {
        let u = self.pull_direction(position_m, 0);
        let m = settings.field.magnitude_n;
        // The field: F1 keeps its constant direction, F2's bisector of one wire is the wire.
        let field = if m.is_finite() && m != 0.0 {
            match settings.algorithm.field_rule() {
                crate::distribution::FieldRule::Bisector => u * m,
                crate::distribution::FieldRule::Constant => {
                    let d = settings.field.direction;
                    let n = d.norm();
                    if n > 1e-12 && n.is_finite() {
                        d * (m / n)
                    } else {
                        u * m
                    }
                }
            }
        } else if settings.free_space_field_n > 0.0 {
            let fs = settings
                .free_space_field_n
                .max(settings.limits.t_min_n)
                .min(settings.limits.t_max_n);
            u * (fs * free_space_pull_share(in_contact, desired_n.norm(), fs))
        } else {
            Vec3::zeros()
        };
        let field = field * scale;
        let target = desired_n + field;
        let d = one_wire_distribute(
            &(position_m - self.guide_m),
            &target,
            settings.algorithm,
            &settings.limits,
        );
        let exact = (d.rendered_n - target).norm() <= 1e-9 * (1.0 + target.norm());
        Some(DeviceForces {
            field_force_n: field,
            target_force_n: target,
            tensions: WireTensions {
                tensions_n: [d.tension_n],
                rendered_n: d.rendered_n,
                saturated: d.saturated,
                projected: !exact,
            },
        })
    }
}

/// Every wire at `t_min` and the force that makes at `position_m` (the safe state, or a
/// singular configuration).
pub fn minimum_tensions<const N: usize, D: WireDevice<N>>(
    device: &D,
    position_m: &Vec3,
    limits: &ForceLimits,
) -> WireTensions<N> {
    let tensions_n = [clamp_tension(limits.t_min_n, limits); N];
    WireTensions {
        tensions_n,
        rendered_n: device.force_of(position_m, &tensions_n),
        saturated: false,
        projected: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::Algorithm;
    use crate::spidar::Rig4;

    fn settings(algorithm: Algorithm) -> ForceSettings {
        ForceSettings {
            algorithm,
            limits: ForceLimits::default(),
            field: ForceField::none(),
            free_space_field_n: 0.5,
        }
    }

    /// The WireMan on the paper's 370 mm x 300 mm frame.
    fn paper_rig3() -> Rig3 {
        Rig3::paper_frame()
    }

    fn round_trip<const N: usize, D: WireDevice<N>>(device: &D, p: Vec3) {
        let sensed = Sensed {
            lengths_m: device.inverse(&p),
            angles_rad: device.passive_angles(&p),
            ..Sensed::default()
        };
        let fk = device.forward(&sensed);
        assert!(!fk.clamped, "{:?} at {p:?}", D::KIND);
        assert!(
            (fk.position_m - p).norm() < 1e-9,
            "{:?}: {:?} != {p:?}",
            D::KIND,
            fk.position_m
        );
    }

    #[test]
    fn every_device_inverts_its_kinematics() {
        let rig3 = paper_rig3();
        round_trip(&rig3, Vec3::new(0.2, 0.1, 0.3));
        round_trip(&PlanarDevice::paper_prototype(), Vec3::new(0.3, 0.0, 0.2));
        round_trip(&PolarDevice::at_origin(), Vec3::new(0.1, -0.2, 0.35));
        let polar = PolarDevice::new(Vec3::new(0.1, 0.2, 0.0)).unwrap();
        round_trip(&polar, Vec3::new(0.15, -0.1, 0.4));
        round_trip(&Rig4::cube_frame(), Vec3::new(0.2, 0.15, 0.3));
    }

    #[test]
    fn each_wire_from_its_guide_agrees_with_the_kinematics() {
        fn check<const N: usize, D: WireDevice<N>>(device: &D, p: Vec3) {
            let lengths = device.inverse(&p);
            for i in 0..N {
                let (unit, length) = device.wire_from_guide(&p, i);
                assert!(
                    (length - lengths[i]).abs() < 1e-12,
                    "{:?} wire {i}",
                    D::KIND
                );
                assert!((unit + device.pull_direction(&p, i)).norm() < 1e-12);
                assert!((unit.norm() - 1.0).abs() < 1e-12);
            }
        }
        let rig3 = paper_rig3();
        check(&rig3, Vec3::new(0.2, 0.1, 0.3));
        check(&PlanarDevice::paper_prototype(), Vec3::new(0.3, 0.0, 0.2));
        check(&PolarDevice::at_origin(), Vec3::new(0.1, -0.2, 0.35));
        check(&Rig4::cube_frame(), Vec3::new(0.2, 0.15, 0.3));
    }

    #[test]
    fn velocity_matches_finite_differences() {
        fn check<const N: usize, D: WireDevice<N>>(device: &D, p: Vec3, v: Vec3) {
            let h = 1e-6;
            let q = p + v * h;
            let (l0, l1) = (device.inverse(&p), device.inverse(&q));
            let (a0, a1) = (device.passive_angles(&p), device.passive_angles(&q));
            let sensed = Sensed {
                lengths_m: l0,
                length_rates_m_s: core::array::from_fn(|i| (l1[i] - l0[i]) / h),
                angles_rad: a0,
                angle_rates_rad_s: core::array::from_fn(|i| (a1[i] - a0[i]) / h),
            };
            let got = device.velocity(&p, &sensed).unwrap();
            assert!((got - v).norm() < 1e-4, "{:?}: {got:?} != {v:?}", D::KIND);
        }
        check(
            &PlanarDevice::paper_prototype(),
            Vec3::new(0.26, 0.0, 0.26),
            Vec3::new(0.1, 0.0, -0.05),
        );
        check(
            &PolarDevice::at_origin(),
            Vec3::new(0.1, 0.2, 0.3),
            Vec3::new(0.1, -0.2, 0.05),
        );
        check(
            &Rig4::cube_frame(),
            Vec3::new(0.2, 0.15, 0.3),
            Vec3::new(0.1, -0.2, 0.05),
        );
    }

    #[test]
    fn the_planar_device_renders_in_its_plane() {
        let d = PlanarDevice::paper_prototype();
        let p = Vec3::new(0.26, 0.0, 0.26);
        // A push towards the guides (region A) with an out-of-plane part.
        let f = d
            .forces(
                &p,
                &Vec3::new(0.0, 3.0, -2.0),
                true,
                1.0,
                &settings(Algorithm::P2),
            )
            .unwrap();
        assert!((f.target_force_n - Vec3::new(0.0, 0.0, -2.0)).norm() < 1e-12);
        assert!((f.tensions.rendered_n - f.target_force_n).norm() < 1e-9);
        assert_eq!(f.tensions.rendered_n.y, 0.0);
        assert!(!f.tensions.projected);
    }

    #[test]
    fn the_single_wire_makes_only_pulls_along_itself() {
        let d = PolarDevice::at_origin();
        let p = Vec3::new(0.0, 0.0, 0.4);
        let s = settings(Algorithm::P2);
        // Along the wire, towards the guide: exact.
        let f = d
            .forces(&p, &Vec3::new(0.0, 0.0, -3.0), true, 1.0, &s)
            .unwrap();
        assert!((f.tensions.tensions_n[0] - 3.0).abs() < 1e-9);
        assert!(!f.tensions.projected);
        // Away from the guide: only the tension floor, and said to be projected.
        let f = d
            .forces(&p, &Vec3::new(0.0, 0.0, 3.0), true, 1.0, &s)
            .unwrap();
        assert_eq!(f.tensions.tensions_n[0], s.limits.t_min_n);
        assert!(f.tensions.projected);
        // Free space: the pull along the wire.
        let f = d.forces(&p, &Vec3::zeros(), false, 1.0, &s).unwrap();
        assert!((f.tensions.rendered_n - Vec3::new(0.0, 0.0, -0.5)).norm() < 1e-9);
    }

    #[test]
    fn minimum_tensions_render_the_floor() {
        let d = PlanarDevice::paper_prototype();
        let p = Vec3::new(0.26, 0.0, 0.26);
        let m = minimum_tensions(&d, &p, &ForceLimits::default());
        assert_eq!(m.tensions_n, [0.3; 2]);
        assert!((m.rendered_n - Vec3::new(0.0, 0.0, -0.3 * 2f64.sqrt())).norm() < 1e-9);
    }
}
