//! The planar two-wire device of the paper's experiments (section 6).
//!
//! The thimble moves in the x-z plane (`y = 0`); the two guides lie on the x axis at
//! `x_0` and `x_1` (the prototype: 0 and 0.52 m). Positions are `[x, z]`, `z > 0` in front of the
//! guides. Eqs. (1)-(6) with `y = 0`.

use nalgebra::{Matrix2, Vector2};

use crate::kinematics::{libm_sqrt, RigError, MIN_GUIDE_DISTANCE_M};
use crate::wire_map::WireMap;

/// A planar position or force, `[x, z]` (metres or newtons).
pub type Vec2 = Vector2<f64>;

/// Result of planar forward kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanarForward {
    /// Thimble position `[x, z]`, metres.
    pub position_m: Vec2,
    /// True when the lengths were inconsistent (noise near the guide line) and `z` was clamped
    /// to 0, or the input was not finite.
    pub clamped: bool,
}

/// A planar two-wire rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigPlanar {
    guides_x_m: [f64; 2],
}

impl RigPlanar {
    /// A rig with guides at `x = guides_x_m[0]` and `x = guides_x_m[1]` on the x axis.
    pub fn new(guides_x_m: [f64; 2]) -> Result<RigPlanar, RigError> {
        if !guides_x_m.iter().all(|x| x.is_finite()) {
            return Err(RigError::NotFinite);
        }
        let distance_m = (guides_x_m[1] - guides_x_m[0]).abs();
        if distance_m < MIN_GUIDE_DISTANCE_M {
            return Err(RigError::GuidesTooClose { distance_m });
        }
        Ok(RigPlanar { guides_x_m })
    }

    /// The paper's prototype: guides at `x_0 = 0`, `x_1 = 0.52` m.
    pub fn paper_prototype() -> RigPlanar {
        RigPlanar {
            guides_x_m: [0.0, 0.52],
        }
    }

    /// Guide positions along x, metres.
    pub fn guides_x_m(&self) -> [f64; 2] {
        self.guides_x_m
    }

    /// Inverse kinematics (eq. 1 with `y = 0`): wire lengths for a position `[x, z]`.
    pub fn inverse(&self, position_m: &Vec2) -> [f64; 2] {
        let l = |g: f64| {
            let dx = position_m.x - g;
            libm_sqrt(dx * dx + position_m.y * position_m.y)
        };
        [l(self.guides_x_m[0]), l(self.guides_x_m[1])]
    }

    /// Forward kinematics (eq. 2 with `y = 0`): position with `z >= 0`. Inconsistent lengths
    /// clamp `z` to 0 and say so; never NaN.
    pub fn forward(&self, lengths_m: &[f64; 2]) -> PlanarForward {
        let [g0, g1] = self.guides_x_m;
        let [l0, l1] = *lengths_m;
        // (x-g0)² - (x-g1)² = l0² - l1²  =>  x = (l0² - l1² + g1² - g0²) / (2 (g1 - g0))
        let x = (l0 * l0 - l1 * l1 + g1 * g1 - g0 * g0) / (2.0 * (g1 - g0));
        let dx = x - g0;
        let z_sq = l0 * l0 - dx * dx;
        let (z, clamped) = if z_sq >= 0.0 {
            (libm_sqrt(z_sq), false)
        } else {
            (0.0, true)
        };
        if x.is_finite() && z.is_finite() {
            PlanarForward {
                position_m: Vec2::new(x, z),
                clamped,
            }
        } else {
            PlanarForward {
                position_m: Vec2::new(0.5 * (g0 + g1), 0.0),
                clamped: true,
            }
        }
    }

    /// Unit vectors `v_i` from the guides to the thimble (eq. 3) as columns.
    pub fn wire_directions(&self, position_m: &Vec2) -> Matrix2<f64> {
        let mut m = Matrix2::zeros();
        for (i, g) in self.guides_x_m.iter().enumerate() {
            let d = Vec2::new(position_m.x - g, position_m.y);
            let n = d.norm();
            let v = if n > 1e-12 { d / n } else { Vec2::y() };
            m.set_column(i, &v);
        }
        m
    }

    /// The force map at `position_m` (eqs. 4-5), `None` on the guide line.
    pub fn wire_map(&self, position_m: &Vec2) -> Option<WireMap<2>> {
        WireMap::<2>::from_pull(-self.wire_directions(position_m))
    }

    /// Thimble velocity from wire rates (eq. 6), `None` where singular. Rates positive = paying
    /// out.
    pub fn velocity_from_rates(
        &self,
        position_m: &Vec2,
        length_rates_m_s: &[f64; 2],
    ) -> Option<Vec2> {
        let inv = self.wire_directions(position_m).transpose().try_inverse()?;
        Some(inv * Vec2::new(length_rates_m_s[0], length_rates_m_s[1]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn prototype_point_has_orthogonal_wires() {
        let rig = RigPlanar::paper_prototype();
        let p = Vec2::new(0.26, 0.26);
        let map = rig.wire_map(&p).unwrap();
        let u0 = map.pull_direction(0);
        let u1 = map.pull_direction(1);
        assert!(u0.dot(&u1).abs() < 1e-12, "vertex angle is 90 degrees");
        assert!((map.bisector() - Vec2::new(0.0, -1.0)).norm() < 1e-12);
        let l = rig.inverse(&p);
        assert!((l[0] - 0.26 * core::f64::consts::SQRT_2).abs() < 1e-12);
    }

    #[test]
    fn bad_geometry_is_refused_and_noise_clamps() {
        assert!(matches!(
            RigPlanar::new([0.1, 0.105]),
            Err(RigError::GuidesTooClose { .. })
        ));
        assert_eq!(
            RigPlanar::new([0.0, f64::INFINITY]),
            Err(RigError::NotFinite)
        );
        let rig = RigPlanar::paper_prototype();
        let mut l = rig.inverse(&Vec2::new(0.1, 0.0));
        l[0] -= 1e-3;
        let s = rig.forward(&l);
        assert!(s.clamped && s.position_m.y == 0.0 && s.position_m.x.is_finite());
        let s = rig.forward(&[f64::NAN, 0.2]);
        assert!(s.clamped && s.position_m.iter().all(|c| c.is_finite()));
        assert!(rig.wire_map(&Vec2::new(0.3, 0.0)).is_none());
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]
        #[test]
        fn round_trip_and_velocity(x in -0.3f64..0.8, z in 0.02f64..0.7, vx in -0.5f64..0.5, vz in -0.5f64..0.5) {
            let rig = RigPlanar::paper_prototype();
            let p = Vec2::new(x, z);
            let s = rig.forward(&rig.inverse(&p));
            prop_assert!(!s.clamped);
            prop_assert!((s.position_m - p).norm() < 1e-9);
            let v = Vec2::new(vx, vz);
            let h = 1e-7;
            let l0 = rig.inverse(&p);
            let l1 = rig.inverse(&(p + v * h));
            let rates = [(l1[0] - l0[0]) / h, (l1[1] - l0[1]) / h];
            let back = rig.velocity_from_rates(&p, &rates).unwrap();
            prop_assert!((back - v).norm() < 1e-4 * (1.0 + v.norm()) / z.min(1.0));
        }
    }
}
