//! The one-wire "defective" device (paper section 4.4, eq. 7, Fig. 11).
//!
//! One actuated wire from a guide at the origin; two passive angles measured by sensors: the
//! azimuth `alpha` (in the x-y plane from +x towards +y) and the elevation `beta` (from the x-y
//! plane towards +z). Only the tension of the wire is controlled, so the only force the device can
//! make is a pull along `-v = -x_t / l`.

use nalgebra::Matrix3;

use crate::distribution::{clamp_tension, Algorithm, ForceLimits, Projection};
use crate::kinematics::libm_sqrt;
use crate::Vec3;

/// Polar coordinates of the thimble of the one-wire device.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PolarCoordinates {
    /// Wire length `l`, metres.
    pub length_m: f64,
    /// Azimuth `alpha`, radians.
    pub azimuth_rad: f64,
    /// Elevation `beta`, radians.
    pub elevation_rad: f64,
}

/// Forward kinematics (eq. 7, left): position from `l, alpha, beta`.
pub fn polar_forward(c: &PolarCoordinates) -> Vec3 {
    let (sa, ca) = libm_sincos(c.azimuth_rad);
    let (sb, cb) = libm_sincos(c.elevation_rad);
    Vec3::new(c.length_m * cb * ca, c.length_m * cb * sa, c.length_m * sb)
}

/// Inverse kinematics (eq. 7, right): `l, alpha, beta` from the position.
pub fn polar_inverse(position_m: &Vec3) -> PolarCoordinates {
    let rho = libm_sqrt(position_m.x * position_m.x + position_m.y * position_m.y);
    PolarCoordinates {
        length_m: position_m.norm(),
        azimuth_rad: libm_atan2(position_m.y, position_m.x),
        elevation_rad: libm_atan2(position_m.z, rho),
    }
}

/// Jacobian `d x_t / d(l, alpha, beta)` of eq. 7 (columns: per metre of wire, per radian of
/// azimuth, per radian of elevation). Thimble velocity = this times the coordinate rates.
pub fn polar_jacobian(c: &PolarCoordinates) -> Matrix3<f64> {
    let (sa, ca) = libm_sincos(c.azimuth_rad);
    let (sb, cb) = libm_sincos(c.elevation_rad);
    let l = c.length_m;
    Matrix3::new(
        cb * ca,
        -l * cb * sa,
        -l * sb * ca,
        cb * sa,
        l * cb * ca,
        -l * sb * sa,
        sb,
        0.0,
        l * cb,
    )
}

/// What the one-wire device renders for a desired force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OneWireDistribution {
    /// Tension set-point, newtons, within the limits.
    pub tension_n: f64,
    /// Force on the thimble, newtons (always along the wire, towards the guide).
    pub rendered_n: Vec3,
    /// The tension hit `t_max`.
    pub saturated: bool,
}

/// Tension of the single wire for `desired_n` at `position_m`. The wire pulls along `u = -v`.
/// P1 and the field algorithms use `t = u·f` (the component along the wire, floored at `t_min`);
/// P2 and QP make the force along `n = f/|f|` exact where possible, `t = |f| / (n·u)` when
/// `n·u > 0` (the sphere `S_f` degenerates to a point: only forces along the wire are exact).
pub fn one_wire_distribute(
    position_m: &Vec3,
    desired_n: &Vec3,
    algorithm: Algorithm,
    limits: &ForceLimits,
) -> OneWireDistribution {
    let l = position_m.norm();
    let u = if l > 1e-12 && l.is_finite() {
        -position_m / l
    } else {
        -Vec3::z()
    };
    let magnitude = desired_n.norm();
    let along = u.dot(desired_n);
    let raw = match algorithm.projection() {
        Projection::ClampNegative => along,
        Projection::ExactAlongNormal | Projection::NormalFirstNearest => {
            let a = if magnitude > 1e-12 {
                along / magnitude
            } else {
                0.0
            };
            if a > 1e-3 {
                magnitude / a
            } else {
                limits.t_min_n
            }
        }
    };
    let raw = if raw.is_finite() { raw } else { limits.t_min_n };
    let tension_n = clamp_tension(raw, limits);
    OneWireDistribution {
        tension_n,
        rendered_n: u * tension_n,
        saturated: raw > limits.t_max_n,
    }
}

#[inline]
fn libm_sincos(x: f64) -> (f64, f64) {
    (
        nalgebra::ComplexField::sin(x),
        nalgebra::ComplexField::cos(x),
    )
}

#[inline]
fn libm_atan2(y: f64, x: f64) -> f64 {
    nalgebra::RealField::atan2(y, x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn only_forces_along_the_wire_are_rendered() {
        let p = Vec3::new(0.1, 0.2, 0.3);
        let limits = ForceLimits {
            t_min_n: 0.2,
            t_max_n: 15.0,
        };
        let along = -p.normalize() * 2.0;
        for alg in [Algorithm::P1, Algorithm::P2, Algorithm::Qp] {
            let d = one_wire_distribute(&p, &along, alg, &limits);
            assert!((d.rendered_n - along).norm() < 1e-12, "{alg:?}");
        }
        // Sideways with a pull component: P2 gets the normal component exact, P1 the wire one.
        let f = Vec3::new(1.0, 0.0, 0.0) + along * 0.5;
        let n = f.normalize();
        let d2 = one_wire_distribute(&p, &f, Algorithm::P2, &limits);
        assert!((d2.rendered_n.dot(&n) - f.norm()).abs() < 1e-9);
        let d1 = one_wire_distribute(&p, &f, Algorithm::P1, &limits);
        assert!((d1.tension_n - (-p.normalize()).dot(&f)).abs() < 1e-12);
        // Pushing away from the guide: only t_min.
        let d = one_wire_distribute(&p, &(p * 10.0), Algorithm::P2, &limits);
        assert_eq!(d.tension_n, 0.2);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(3), ..ProptestConfig::default() })]
        #[test]
        fn polar_round_trip_and_jacobian(l in 0.05f64..0.8, a in -3.1f64..3.1, b in -1.5f64..1.5) {
            let c = PolarCoordinates { length_m: l, azimuth_rad: a, elevation_rad: b };
            let p = polar_forward(&c);
            let back = polar_inverse(&p);
            prop_assert!((back.length_m - l).abs() < 1e-12);
            prop_assert!((back.azimuth_rad - a).abs() < 1e-9);
            prop_assert!((back.elevation_rad - b).abs() < 1e-9);
            let h = 1e-7;
            let j = polar_jacobian(&c);
            let dp = polar_forward(&PolarCoordinates { length_m: l + h, azimuth_rad: a + h, elevation_rad: b + h }) - p;
            prop_assert!((j * Vec3::new(h, h, h) - dp).norm() < 1e-11);
        }
    }
}
