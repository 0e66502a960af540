//! The one-wire "defective" device (paper section 4.4, eq. 7, Fig. 11).
//!
//! One actuated wire from a guide at the origin; two passive angles measured by sensors: the
//! azimuth `alpha` (in the x-y plane from +x towards +y) and the elevation `beta` (from the x-y
//! plane towards +z). Only the tension of the wire is controlled, so the only force the device can
//! make is a pull along `-v = -x_t / l`.

use nalgebra::Matrix3;

use crate::distribution::{
    clamp_tension, normal_weight_fade, Algorithm, ForceLimits, Projection, NORMAL_WEIGHT,
};
use crate::felt::FELT_MARGIN_N;
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

/// Tension of the single wire for `desired_n` at `position_m`. The wire pulls along `u = -v`;
/// `a = n·u` with `n = f/|f|`, `t1 = clamp(u·f)` (P1: the component along the wire).
/// - P1: `t1`.
/// - P2 (and F1, F2): the least change of `t1` that makes the force along `n` close to `|f|`:
///   minimise `κφ (a t − |f|)² + (t − t1)²`, `t = (t1 + κφ a |f|) / (1 + κφ a²)`.
/// - QP: the nearest force, the error along `n` weighed `1 + κφ` times:
///   `t = (u·f + κφ a |f|) / (1 + κφ a²)`.
///
/// `κ` = [`NORMAL_WEIGHT`](crate::distribution::NORMAL_WEIGHT), `φ` =
/// [`normal_weight_fade`](crate::distribution::normal_weight_fade) with the floor `t_min`: a
/// force along the wire is exact; one turning across the wire fades to `t1` continuously, so the
/// paper's `t = |f| / (n·u)`, which jumps from `t_max` to `t_min` where `n·u` crosses a threshold,
/// never hits the finger. The felt bound holds: `t <= |f| + t_min + FELT_MARGIN_N`.
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
    let first = clamp_tension(along, limits);
    let a = if magnitude > 1e-12 {
        along / magnitude
    } else {
        0.0
    };
    let weight = NORMAL_WEIGHT * normal_weight_fade(magnitude, limits.t_min_n);
    let raw = match algorithm.projection() {
        Projection::ClampNegative => along,
        Projection::ExactAlongNormal => (first + weight * a * magnitude) / (1.0 + weight * a * a),
        Projection::NormalFirstNearest => (along + weight * a * magnitude) / (1.0 + weight * a * a),
    };
    let raw = if raw.is_finite() { raw } else { limits.t_min_n };
    let felt_limit = magnitude + limits.t_min_n + FELT_MARGIN_N;
    let tension_n = clamp_tension(raw.min(felt_limit), limits);
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
        // Sideways with a pull component: P1 renders the wire's component; P2 and QP more of
        // the normal one, up to the felt bound (|f| + t_min + margin), which holds them here.
        let f = Vec3::new(1.0, 0.0, 0.0) + along * 0.5;
        let n = f.normalize();
        let d1 = one_wire_distribute(&p, &f, Algorithm::P1, &limits);
        assert!((d1.tension_n - (-p.normalize()).dot(&f)).abs() < 1e-12);
        for alg in [Algorithm::P2, Algorithm::Qp] {
            let d = one_wire_distribute(&p, &f, alg, &limits);
            assert!((d.tension_n - (f.norm() + 0.2 + FELT_MARGIN_N)).abs() < 1e-12);
            assert!(d.rendered_n.dot(&n) > d1.rendered_n.dot(&n));
        }
        // Across the wire, P2's t = |f| / (n·u) no longer jumps from t_max to t_min where n·u
        // crosses zero: it fades to P1's floor.
        let across = Vec3::new(-p.y, p.x, 0.0).normalize() * 3.0;
        for tilt in [1e-3, 1e-6, 0.0, -1e-6] {
            let g = across - p.normalize() * tilt;
            for alg in [Algorithm::P2, Algorithm::Qp] {
                let d = one_wire_distribute(&p, &g, alg, &limits);
                let lipschitz = crate::distribution::NORMAL_WEIGHT * tilt.abs();
                assert!(
                    d.tension_n <= 0.2 + lipschitz + 1e-12,
                    "tilt {tilt}: {}",
                    d.tension_n
                );
            }
        }
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
