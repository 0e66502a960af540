//! A four-wire device (SPIDAR-style): wires from four guides around the workspace, not in one
//! plane, converge on the thimble. Inside the guides' tetrahedron the wires can make a force in
//! every direction, with every wire taut: the fourth wire is what a three-wire device lacks to
//! render the surfaces whose normal points away from its guides (regions B and C).
//!
//! Kinematics: `|p - g_i|² - |p - g_0|² = l_i² - l_0²` is linear in `p` (three equations, one
//! solution when the guides are not coplanar). Tensions: `V t = f` has a one-dimensional family
//! of solutions `t = t_p + λ h` (`t_p = V^T (V V^T)^-1 f` the least-norm one, `h` spanning the
//! null space of `V`); the quadratic programme `min |t|² s.t. V t = f, t_min <= t_i <= t_max`
//! is solved exactly by the `λ` nearest zero in the feasible interval. A force beyond what the
//! limits allow is scaled down along its direction to the largest feasible one.

use nalgebra::{Matrix3, Matrix3x4, Vector4};

use crate::distribution::{clamp_tension, ForceLimits};
use crate::kinematics::{ForwardSolution, RigError};
use crate::wire_device::{
    unit_and_length, DeviceForces, DeviceKind, ForceSettings, Sensed, WireDevice, WireTensions,
};
use crate::Vec3;

/// Smallest volume of the guide tetrahedron accepted, m³.
pub const MIN_TETRAHEDRON_VOLUME_M3: f64 = 1e-4;

/// A four-wire rig with guides anywhere, not coplanar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig4 {
    guides_m: [Vec3; 4],
    fk_inverse: Matrix3<f64>,
}

impl Rig4 {
    /// A rig with guides at `guides_m`; rejected when not finite or (nearly) coplanar.
    pub fn new(guides_m: [Vec3; 4]) -> Result<Rig4, RigError> {
        if !guides_m.iter().all(|g| g.iter().all(|c| c.is_finite())) {
            return Err(RigError::NotFinite);
        }
        let a = Matrix3::from_rows(&[
            ((guides_m[1] - guides_m[0]) * 2.0).transpose(),
            ((guides_m[2] - guides_m[0]) * 2.0).transpose(),
            ((guides_m[3] - guides_m[0]) * 2.0).transpose(),
        ]);
        let volume_m3 = a.determinant().abs() / 48.0;
        if volume_m3 < MIN_TETRAHEDRON_VOLUME_M3 {
            return Err(RigError::Degenerate { area_m2: volume_m3 });
        }
        let fk_inverse = a
            .try_inverse()
            .ok_or(RigError::Degenerate { area_m2: 0.0 })?;
        Ok(Rig4 {
            guides_m,
            fk_inverse,
        })
    }

    /// Four alternating corners of a 0.6 m cube around the WireMan's workspace (x from -0.1 to
    /// 0.5, y from -0.15 to 0.45, z from 0 to 0.6 m): two guides on the body's plane, two in
    /// front of the hand.
    pub fn cube_frame() -> Rig4 {
        Rig4::new([
            Vec3::new(-0.1, -0.15, 0.0),
            Vec3::new(0.5, 0.45, 0.0),
            Vec3::new(0.5, -0.15, 0.6),
            Vec3::new(-0.1, 0.45, 0.6),
        ])
        .expect("the cube frame is a valid rig")
    }

    /// The guide points, metres.
    pub fn guides_m(&self) -> &[Vec3; 4] {
        &self.guides_m
    }

    /// Unit vectors from the guides to the thimble, as columns (`+z` for a zero-length wire).
    pub fn wire_directions(&self, position_m: &Vec3) -> Matrix3x4<f64> {
        let mut m = Matrix3x4::zeros();
        for (i, g) in self.guides_m.iter().enumerate() {
            let d = position_m - g;
            let n = d.norm();
            let v = if n > 1e-12 { d / n } else { Vec3::z() };
            m.set_column(i, &v);
        }
        m
    }

    /// The tensions of the quadratic programme for `target_n` at `position_m`, or `None` where
    /// the wires are degenerate there.
    pub fn tensions(
        &self,
        position_m: &Vec3,
        target_n: &Vec3,
        limits: &ForceLimits,
    ) -> Option<WireTensions<4>> {
        let pull = -self.wire_directions(position_m);
        let gram_inverse = (pull * pull.transpose()).try_inverse()?;
        let pinv = pull.transpose() * gram_inverse;
        // Null space of V by cofactors: h_i = (-1)^i det(V without column i).
        let minor = |skip: usize| {
            let mut m = Matrix3::zeros();
            let mut c = 0;
            for i in 0..4 {
                if i != skip {
                    m.set_column(c, &pull.column(i));
                    c += 1;
                }
            }
            m.determinant()
        };
        let mut h = Vector4::new(minor(0), -minor(1), minor(2), -minor(3));
        let norm = h.norm();
        if !(norm > 1e-12 && norm.is_finite()) {
            return None;
        }
        h /= norm;
        if h.sum() < 0.0 {
            h = -h;
        }
        let target = if target_n.iter().all(|c| c.is_finite()) {
            *target_n
        } else {
            Vec3::zeros()
        };
        let tp = pinv * target;
        let (tensions, projected) = match feasible_lambda(&tp, &h, limits) {
            Some(lambda) => (tp + h * lambda, false),
            None => {
                // Largest fraction of the target the limits allow (bounded bisection).
                let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
                let mut best = feasible_lambda(&Vector4::zeros(), &h, limits).map(|l| h * l);
                for _ in 0..40 {
                    let mid = 0.5 * (lo + hi);
                    match feasible_lambda(&(tp * mid), &h, limits) {
                        Some(l) => {
                            lo = mid;
                            best = Some(tp * mid + h * l);
                        }
                        None => hi = mid,
                    }
                }
                let floor = clamp_tension(limits.t_min_n, limits);
                (best.unwrap_or(Vector4::repeat(floor)), true)
            }
        };
        let mut out = WireTensions {
            projected,
            ..WireTensions::default()
        };
        let at_max = limits.t_max_n * (1.0 - 1e-9);
        for i in 0..4 {
            out.tensions_n[i] = clamp_tension(tensions[i], limits);
            if projected && tensions[i] >= at_max {
                out.saturated = true;
            }
        }
        out.rendered_n = pull * Vector4::from(out.tensions_n);
        Some(out)
    }
}

/// The `λ` nearest zero with `t_min <= tp + λ h <= t_max`, or `None` when there is none.
fn feasible_lambda(tp: &Vector4<f64>, h: &Vector4<f64>, limits: &ForceLimits) -> Option<f64> {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..4 {
        let (a, b) = (limits.t_min_n - tp[i], limits.t_max_n - tp[i]);
        if h[i] > 1e-12 {
            lo = lo.max(a / h[i]);
            hi = hi.min(b / h[i]);
        } else if h[i] < -1e-12 {
            lo = lo.max(b / h[i]);
            hi = hi.min(a / h[i]);
        } else if a > 1e-12 || b < -1e-12 {
            return None;
        }
    }
    (lo <= hi + 1e-12).then(|| 0.0_f64.max(lo).min(hi))
}

impl WireDevice<4> for Rig4 {
    const KIND: DeviceKind = DeviceKind::Spidar4;

    fn forward(&self, sensed: &Sensed<4>) -> ForwardSolution {
        let g = &self.guides_m;
        let l = &sensed.lengths_m;
        let b = Vec3::new(
            l[0] * l[0] - l[1] * l[1] + g[1].norm_squared() - g[0].norm_squared(),
            l[0] * l[0] - l[2] * l[2] + g[2].norm_squared() - g[0].norm_squared(),
            l[0] * l[0] - l[3] * l[3] + g[3].norm_squared() - g[0].norm_squared(),
        );
        let p = self.fk_inverse * b;
        if p.iter().all(|c| c.is_finite()) {
            ForwardSolution {
                position_m: p,
                clamped: false,
            }
        } else {
            ForwardSolution {
                position_m: (g[0] + g[1] + g[2] + g[3]) / 4.0,
                clamped: true,
            }
        }
    }

    fn velocity(&self, position_m: &Vec3, sensed: &Sensed<4>) -> Option<Vec3> {
        // l̇ = W^T ẋ, least squares: ẋ = (W W^T)^-1 W l̇.
        let w = self.wire_directions(position_m);
        let inv = (w * w.transpose()).try_inverse()?;
        Some(inv * (w * Vector4::from(sensed.length_rates_m_s)))
    }

    fn inverse(&self, position_m: &Vec3) -> [f64; 4] {
        core::array::from_fn(|i| (position_m - self.guides_m[i]).norm())
    }

    fn pull_direction(&self, position_m: &Vec3, wire: usize) -> Vec3 {
        -self.wire_from_guide(position_m, wire).0
    }

    fn wire_from_guide(&self, position_m: &Vec3, wire: usize) -> (Vec3, f64) {
        unit_and_length(position_m - self.guides_m[wire])
    }

    fn forces(
        &self,
        position_m: &Vec3,
        desired_n: &Vec3,
        _in_contact: bool,
        scale: f64,
        settings: &ForceSettings,
    ) -> Option<DeviceForces<4>> {
        // Every direction is reachable: a field is only the one configured (F2's bisector has
        // no meaning here and takes the configured direction too); free space needs no pull,
        // the wires' internal tension keeps them taut.
        let m = settings.field.magnitude_n;
        let field = if m.is_finite() && m != 0.0 {
            let d = settings.field.direction;
            let n = d.norm();
            let dir = if n > 1e-12 && n.is_finite() {
                d / n
            } else {
                -Vec3::z()
            };
            dir * m * scale
        } else {
            Vec3::zeros()
        };
        let target = desired_n + field;
        let tensions = self.tensions(position_m, &target, &settings.limits)?;
        Some(DeviceForces {
            field_force_n: field,
            target_force_n: target,
            tensions,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn every_direction_is_rendered_at_the_centre() {
        let rig = Rig4::cube_frame();
        let p = Vec3::new(0.2, 0.15, 0.3);
        let limits = ForceLimits::default();
        for k in 0..24 {
            let a = k as f64 * core::f64::consts::TAU / 24.0;
            for f in [
                Vec3::new(a.cos(), a.sin(), 0.0) * 3.0,
                Vec3::new(a.cos(), 0.0, a.sin()) * 3.0,
            ] {
                let t = rig.tensions(&p, &f, &limits).unwrap();
                assert!(!t.projected, "{f:?}: {t:?}");
                assert!((t.rendered_n - f).norm() < 1e-9, "{f:?}: {t:?}");
                assert!(t.tensions_n.iter().all(|&x| x >= limits.t_min_n - 1e-12));
            }
        }
    }

    #[test]
    fn the_least_tension_solution_is_chosen() {
        let rig = Rig4::cube_frame();
        let p = Vec3::new(0.2, 0.15, 0.3);
        let limits = ForceLimits::default();
        let f = Vec3::new(0.0, 0.0, -2.0);
        let t = rig.tensions(&p, &f, &limits).unwrap();
        // Every other solution of V t = f is t + e h (h spans the null space of V): those that
        // keep every wire above the floor have a larger norm.
        let pull = -rig.wire_directions(&p);
        let base = Vector4::from(t.tensions_n);
        let minor = |skip: usize| {
            let cols: [usize; 3] = match skip {
                0 => [1, 2, 3],
                1 => [0, 2, 3],
                2 => [0, 1, 3],
                _ => [0, 1, 2],
            };
            Matrix3::from_columns(&[
                pull.column(cols[0]),
                pull.column(cols[1]),
                pull.column(cols[2]),
            ])
            .determinant()
        };
        let h = Vector4::new(minor(0), -minor(1), minor(2), -minor(3));
        assert!((pull * h).norm() < 1e-9);
        let mut feasible_others = 0;
        for e in [-1e-2, -1e-3, 1e-3, 1e-2] {
            let other = base + h * e;
            if other.iter().all(|&x| x >= limits.t_min_n) {
                feasible_others += 1;
                assert!(other.norm() > base.norm());
            }
        }
        assert!(feasible_others > 0);
        assert!(t
            .tensions_n
            .iter()
            .any(|&x| (x - limits.t_min_n).abs() < 1e-9));
    }

    #[test]
    fn too_large_a_force_is_scaled_along_its_direction() {
        let rig = Rig4::cube_frame();
        let p = Vec3::new(0.2, 0.15, 0.3);
        let f = Vec3::new(0.0, 0.0, 200.0);
        let t = rig.tensions(&p, &f, &ForceLimits::default()).unwrap();
        assert!(t.projected && t.saturated);
        assert!(t.rendered_n.normalize().dot(&f.normalize()) > 1.0 - 1e-6);
        assert!(t.rendered_n.norm() < 200.0 && t.rendered_n.norm() > 5.0);
    }

    #[test]
    fn coplanar_guides_are_rejected() {
        assert!(Rig4::new([
            Vec3::zeros(),
            Vec3::x(),
            Vec3::y(),
            Vec3::new(1.0, 1.0, 0.0)
        ])
        .is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(4), ..ProptestConfig::default() })]
        #[test]
        fn tensions_stay_in_limits_and_never_nan(
            x in -0.05f64..0.45, y in -0.1f64..0.4, z in 0.05f64..0.55,
            fx in -30.0f64..30.0, fy in -30.0f64..30.0, fz in -30.0f64..30.0,
        ) {
            let rig = Rig4::cube_frame();
            let limits = ForceLimits::default();
            if let Some(t) = rig.tensions(&Vec3::new(x, y, z), &Vec3::new(fx, fy, fz), &limits) {
                for v in t.tensions_n {
                    prop_assert!(v.is_finite() && v >= limits.t_min_n && v <= limits.t_max_n);
                }
                prop_assert!(t.rendered_n.iter().all(|c| c.is_finite()));
            }
        }
    }
}
