//! Measures of how well a device renders forces (paper section 6).

use nalgebra::SVector;

use crate::distribution::ForceLimits;
use crate::wire_map::WireMap;

/// The performance index V (eq. 8): `V = f·f_e / |f_e|²` with `f` the rendered force and `f_e`
/// the target (with a field: `f'_e = f_e + f_c`). `V = 1` when the target is rendered exactly
/// (and, more generally, when its component along the target is); `0 < V < 1` when part of it is
/// lost; `V <= 0` when nothing is (a tension floor `t_min > 0` can make it slightly negative).
/// A zero target gives 1 (nothing asked, nothing missed).
pub fn v_index<const N: usize>(rendered_n: &SVector<f64, N>, target_n: &SVector<f64, N>) -> f64 {
    let norm_sq = target_n.norm_squared();
    if norm_sq.is_nan() || norm_sq <= 1e-24 {
        return 1.0;
    }
    let v = rendered_n.dot(target_n) / norm_sq;
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

/// The isotropic force limit at a point: the largest `|f_e|` such that `f_c + f_e` is rendered
/// exactly for *every* direction of `f_e` — the radius of the circle (sphere) `S_f` of the paper's
/// Fig. 16c, centred on the tip of `f_c`.
///
/// The reachable set is the parallelogram (parallelepiped) `{V t : t_min <= t_i <= t_max}`. Its
/// faces are `t_k = t_min` and `t_k = t_max`, i.e. `row_k(J^T)·f = const`, so the distance from
/// `f_c` to face `k` is `(t_k(f_c) - t_min)/|row_k(J^T)|` (resp. `t_max - t_k`). The limit is the
/// smallest of these, or 0 when `f_c` itself is not reachable. With `t_min = 0` and the field on
/// the bisector it is `|f_c| sin(theta/2)`, `theta` the vertex angle of the wires.
pub fn isotropic_force_limit_n<const N: usize>(
    map: &WireMap<N>,
    field_force_n: &SVector<f64, N>,
    limits: &ForceLimits,
) -> f64 {
    let tensions = map.tensions(field_force_n);
    let mut radius = f64::INFINITY;
    for (k, &t) in tensions.iter().enumerate() {
        let gain = map.tension_gain(k);
        if gain.is_nan() || gain <= 0.0 {
            return 0.0;
        }
        radius = radius
            .min((t - limits.t_min_n) / gain)
            .min((limits.t_max_n - t) / gain);
    }
    // (`> 0.0` also maps -0.0 and NaN to 0.)
    if radius.is_finite() && radius > 0.0 {
        radius
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distribution::{project, Projection};
    use crate::planar::{RigPlanar, Vec2};

    #[test]
    fn paper_prototype_isotropic_limit() {
        // x = z = 0.26 m, |f_c| = 2 N along the bisector (-z), t_min = 0: the paper's 1.41 N.
        let map = RigPlanar::paper_prototype()
            .wire_map(&Vec2::new(0.26, 0.26))
            .unwrap();
        let fc = Vec2::new(0.0, -2.0);
        let limits = ForceLimits {
            t_min_n: 0.0,
            t_max_n: 15.0,
        };
        let r = isotropic_force_limit_n(&map, &fc, &limits);
        assert!((r - core::f64::consts::SQRT_2).abs() < 1e-12, "{r}");
        // A tension floor moves the cone's apex: the limit shrinks by exactly t_min here.
        let floor = ForceLimits {
            t_min_n: 0.2,
            t_max_n: 15.0,
        };
        let r_floor = isotropic_force_limit_n(&map, &fc, &floor);
        assert!((r_floor - (core::f64::consts::SQRT_2 - 0.2)).abs() < 1e-12);
        // The limit is tight: every direction renders exactly at r, some direction fails above.
        for projection in [Projection::ClampNegative, Projection::ExactAlongNormal] {
            let mut worst: f64 = 1.0;
            let mut worst_above: f64 = 1.0;
            for deg in 0..360 {
                let a = (deg as f64).to_radians();
                let dir = Vec2::new(a.cos(), a.sin());
                let at = |m: f64| {
                    let target = fc + dir * m;
                    let d = project(&map, &target, projection, &limits);
                    (d.rendered_n - target).norm()
                };
                worst = worst.min(1.0 - at(r * (1.0 - 1e-9)));
                worst_above = worst_above.min(1.0 - at(r * 1.05));
            }
            assert!(worst > 1.0 - 1e-9, "{projection:?}");
            assert!(worst_above < 1.0 - 1e-3, "{projection:?}");
        }
        // Without a field nothing is renderable in every direction.
        assert_eq!(isotropic_force_limit_n(&map, &Vec2::zeros(), &limits), 0.0);
    }

    #[test]
    fn the_bisector_field_maximises_the_isotropic_limit() {
        // An asymmetric spatial cone: the equal-angle bisector beats the mean wire direction and
        // any other nearby direction of the same magnitude.
        let rig = crate::Rig3::new([
            crate::Vec3::zeros(),
            crate::Vec3::new(0.4, 0.0, 0.0),
            crate::Vec3::new(0.05, 0.3, 0.0),
        ])
        .unwrap();
        let map = rig.wire_map(&crate::Vec3::new(0.3, 0.25, 0.2)).unwrap();
        let limits = ForceLimits {
            t_min_n: 0.0,
            t_max_n: 15.0,
        };
        let radius =
            |d: crate::Vec3| isotropic_force_limit_n(&map, &(d.normalize() * 2.0), &limits);
        let best = radius(map.bisector());
        assert!(best > radius(map.mean_pull_direction()) + 1e-3);
        for k in 0..200 {
            let a = k as f64 * 0.7;
            let wobble = crate::Vec3::new(a.cos(), a.sin(), (1.3 * a).cos()) * 0.05;
            assert!(radius(map.bisector() + wobble) <= best + 1e-12);
        }
    }

    #[test]
    fn v_index_cases() {
        let f = Vec2::new(1.0, 0.0);
        assert_eq!(v_index(&f, &f), 1.0);
        assert_eq!(v_index(&Vec2::new(0.5, 0.5), &f), 0.5);
        assert_eq!(v_index(&f, &Vec2::zeros()), 1.0);
        assert_eq!(v_index(&Vec2::new(f64::INFINITY, 0.0), &f), 0.0);
    }
}
