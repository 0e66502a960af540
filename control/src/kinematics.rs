//! Kinematics of the three-wire device (paper section 4.4, eqs. 1-6).
//!
//! The guide points `g_i` lie anywhere in the `z = 0` plane (not only the paper's special frame
//! with `g_0` at the origin and `g_1` on the x axis). With `v_i = (x_t - g_i) / l_i` the unit
//! vectors from the guides to the thimble, the wires pull with tensions `t_i >= 0` and the force
//! on the thimble is `f = V t` with `V = [-v_0, -v_1, -v_2]` (eq. 4); `t = V^-1 f = J^T f` (eq. 5).

use nalgebra::{Matrix2, Matrix3, Vector2};

use crate::wire_map::WireMap;
use crate::Vec3;

/// Why a rig geometry was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RigError {
    /// A guide coordinate is not finite.
    NotFinite,
    /// A guide point is not in the `z = 0` plane.
    NotPlanar,
    /// The guide triangle is degenerate (collinear or coincident points); carries the area in m².
    Degenerate {
        /// Area of the guide triangle, m².
        area_m2: f64,
    },
    /// The two guides of a planar rig are closer than [`MIN_GUIDE_DISTANCE_M`].
    GuidesTooClose {
        /// Distance between the guides, metres.
        distance_m: f64,
    },
}

impl core::fmt::Display for RigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            RigError::NotFinite => f.write_str("guide point coordinates must be finite"),
            RigError::NotPlanar => f.write_str("guide points must lie in the z = 0 plane"),
            RigError::Degenerate { area_m2 } => write!(
                f,
                "guide triangle is degenerate (area {area_m2:.2e} m², needs at least {MIN_TRIANGLE_AREA_M2:.0e} m² and no angle near 0 or 180 degrees)"
            ),
            RigError::GuidesTooClose { distance_m } => write!(
                f,
                "the two guides are {distance_m:.4} m apart, need at least {MIN_GUIDE_DISTANCE_M} m"
            ),
        }
    }
}

/// Smallest guide-triangle area accepted, m² (1 cm²).
pub const MIN_TRIANGLE_AREA_M2: f64 = 1e-4;

/// Smallest distance between two guides accepted, metres (1 cm).
pub const MIN_GUIDE_DISTANCE_M: f64 = 0.01;

/// Result of forward kinematics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForwardSolution {
    /// Thimble position, metres.
    pub position_m: Vec3,
    /// True when the lengths were inconsistent (`l0² - dx² - dy² < 0`, e.g. noise near the guide
    /// plane) and `z` was clamped to 0.
    pub clamped: bool,
}

/// A three-wire rig: guide points in the `z = 0` plane, validated non-degenerate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rig3 {
    guides_m: [Vec3; 3],
    /// Inverse of the 2x2 system of forward kinematics, precomputed.
    fk_inverse: Matrix2<f64>,
}

impl Rig3 {
    /// The paper's WireMan frame: its three guides at the corners of a 370 mm x 300 mm base
    /// triangle in z = 0.
    pub fn paper_frame() -> Rig3 {
        Rig3::new([
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.30, 0.0),
        ])
        .expect("the paper's frame is a valid rig")
    }

    /// Build a rig from three guide points (metres, `z = 0`).
    pub fn new(guides_m: [Vec3; 3]) -> Result<Rig3, RigError> {
        if guides_m
            .iter()
            .any(|g| !(g.x.is_finite() && g.y.is_finite() && g.z.is_finite()))
        {
            return Err(RigError::NotFinite);
        }
        if guides_m.iter().any(|g| g.z.abs() > 1e-9) {
            return Err(RigError::NotPlanar);
        }
        let e1 = guides_m[1] - guides_m[0];
        let e2 = guides_m[2] - guides_m[0];
        let area_m2 = 0.5 * (e1.x * e2.y - e1.y * e2.x).abs();
        // Also reject needle-thin triangles: compare area with the longest side squared.
        let longest = e1
            .norm()
            .max(e2.norm())
            .max((guides_m[2] - guides_m[1]).norm());
        if area_m2 < MIN_TRIANGLE_AREA_M2 || area_m2 < 0.01 * longest * longest {
            return Err(RigError::Degenerate { area_m2 });
        }
        let a = Matrix2::new(e1.x, e1.y, e2.x, e2.y) * 2.0;
        let fk_inverse = a.try_inverse().ok_or(RigError::Degenerate { area_m2 })?;
        Ok(Rig3 {
            guides_m,
            fk_inverse,
        })
    }

    /// A rig with any finite guide points, unchecked: for a plant whose frame may be built
    /// wrong (the twin rehearsing a degenerate base triangle). Its inverse kinematics and wire
    /// directions hold; its forward kinematics means nothing for a degenerate triangle (finite,
    /// but not the thimble). Non-finite coordinates become 0.
    pub fn unchecked(guides_m: [Vec3; 3]) -> Rig3 {
        let guides_m = guides_m.map(|g| g.map(|c| if c.is_finite() { c } else { 0.0 }));
        let e1 = guides_m[1] - guides_m[0];
        let e2 = guides_m[2] - guides_m[0];
        let a = Matrix2::new(e1.x, e1.y, e2.x, e2.y) * 2.0;
        Rig3 {
            guides_m,
            fk_inverse: a.try_inverse().unwrap_or_else(Matrix2::zeros),
        }
    }

    /// The paper's frame from its three base-triangle sides: `g_0` at the origin, `g_1` on the
    /// +x axis, `g_2` in the `z = 0` plane with `y > 0`. Sides in metres: `d01 = |g1-g0|`,
    /// `d02 = |g2-g0|`, `d12 = |g2-g1|`.
    pub fn from_sides(d01_m: f64, d02_m: f64, d12_m: f64) -> Result<Rig3, RigError> {
        if !(d01_m.is_finite() && d02_m.is_finite() && d12_m.is_finite()) || d01_m <= 0.0 {
            return Err(RigError::NotFinite);
        }
        let x2 = (d01_m * d01_m + d02_m * d02_m - d12_m * d12_m) / (2.0 * d01_m);
        let y2_sq = d02_m * d02_m - x2 * x2;
        if y2_sq <= 0.0 {
            return Err(RigError::Degenerate { area_m2: 0.0 });
        }
        Rig3::new([
            Vec3::zeros(),
            Vec3::new(d01_m, 0.0, 0.0),
            Vec3::new(x2, libm_sqrt(y2_sq), 0.0),
        ])
    }

    /// The guide points, metres.
    pub fn guides_m(&self) -> &[Vec3; 3] {
        &self.guides_m
    }

    /// Inverse kinematics (eq. 1): wire lengths for a thimble position.
    pub fn inverse(&self, position_m: &Vec3) -> [f64; 3] {
        let mut l = [0.0; 3];
        for (li, g) in l.iter_mut().zip(self.guides_m.iter()) {
            *li = (position_m - g).norm();
        }
        l
    }

    /// Forward kinematics (eq. 2, generalised to any guide placement): the thimble position
    /// (with `z >= 0`) from the wire lengths. Inconsistent lengths clamp `z` to 0 and say so; the
    /// result is never NaN for finite input.
    pub fn forward(&self, lengths_m: &[f64; 3]) -> ForwardSolution {
        let g = &self.guides_m;
        let sq = |v: &Vec3| v.x * v.x + v.y * v.y;
        // |p-gi|² - |p-g0|² = li² - l0²  =>  2 p·(gi-g0) = l0² - li² + |gi|² - |g0|²
        let b = Vector2::new(
            lengths_m[0] * lengths_m[0] - lengths_m[1] * lengths_m[1] + sq(&g[1]) - sq(&g[0]),
            lengths_m[0] * lengths_m[0] - lengths_m[2] * lengths_m[2] + sq(&g[2]) - sq(&g[0]),
        );
        let xy = self.fk_inverse * b;
        let dx = xy.x - g[0].x;
        let dy = xy.y - g[0].y;
        let z_sq = lengths_m[0] * lengths_m[0] - dx * dx - dy * dy;
        let (z, clamped) = if z_sq >= 0.0 {
            (libm_sqrt(z_sq), false)
        } else {
            (0.0, true)
        };
        let position_m = Vec3::new(xy.x, xy.y, z);
        if position_m.iter().all(|c| c.is_finite()) {
            ForwardSolution {
                position_m,
                clamped,
            }
        } else {
            ForwardSolution {
                position_m: Vec3::zeros(),
                clamped: true,
            }
        }
    }

    /// Unit vectors `v_i = (x_t - g_i)/l_i` (eq. 3) as the columns of a matrix. A wire of zero
    /// length gets the `+z` direction.
    pub fn wire_directions(&self, position_m: &Vec3) -> Matrix3<f64> {
        let mut m = Matrix3::zeros();
        for (i, g) in self.guides_m.iter().enumerate() {
            let d = position_m - g;
            let n = d.norm();
            let v = if n > 1e-12 { d / n } else { Vec3::z() };
            m.set_column(i, &v);
        }
        m
    }

    /// The force map `V = J^-T = [-v_0, -v_1, -v_2]` (eq. 4): `f = V t`.
    pub fn force_matrix(&self, position_m: &Vec3) -> Matrix3<f64> {
        -self.wire_directions(position_m)
    }

    /// The force map at `position_m` (eqs. 3-5), or `None` where it is singular (thimble on or
    /// very near the guide plane, or at a guide).
    pub fn wire_map(&self, position_m: &Vec3) -> Option<WireMap<3>> {
        WireMap::<3>::from_pull(self.force_matrix(position_m))
    }

    /// Tensions `t = J^T f` that make the force `f` (eq. 5), or `None` where `V` is singular
    /// (thimble in the guide plane). Tensions may be negative: projection is the caller's job.
    pub fn tensions_for_force(&self, position_m: &Vec3, force_n: &Vec3) -> Option<[f64; 3]> {
        let v_inv = self.force_matrix(position_m).try_inverse()?;
        let t = v_inv * force_n;
        Some([t.x, t.y, t.z])
    }

    /// Thimble velocity from wire-length rates (eq. 6): `ẋ = J l̇`, with `J = V^-T`. Returns
    /// `None` where singular. Wire rates positive = paying out.
    pub fn velocity_from_rates(
        &self,
        position_m: &Vec3,
        length_rates_m_s: &[f64; 3],
    ) -> Option<Vec3> {
        // l̇_i = v_i · ẋ  =>  W^T ẋ = l̇ with W = [v_0 v_1 v_2]
        let wt = self.wire_directions(position_m).transpose();
        let inv = wt.try_inverse()?;
        Some(
            inv * Vec3::new(
                length_rates_m_s[0],
                length_rates_m_s[1],
                length_rates_m_s[2],
            ),
        )
    }
}

/// `sqrt` that works without std (nalgebra's `libm` through `simba`).
#[inline]
pub(crate) fn libm_sqrt(x: f64) -> f64 {
    nalgebra::ComplexField::sqrt(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn paper_rig() -> Rig3 {
        Rig3::paper_frame()
    }

    #[test]
    fn degenerate_triangles_are_rejected() {
        let collinear = [
            Vec3::zeros(),
            Vec3::new(0.2, 0.0, 0.0),
            Vec3::new(0.4, 0.0, 0.0),
        ];
        assert!(matches!(
            Rig3::new(collinear),
            Err(RigError::Degenerate { .. })
        ));
        let off_plane = [
            Vec3::zeros(),
            Vec3::new(0.3, 0.0, 0.0),
            Vec3::new(0.1, 0.3, 0.01),
        ];
        assert_eq!(Rig3::new(off_plane), Err(RigError::NotPlanar));
        assert!(
            Rig3::from_sides(0.3, 0.1, 0.45).is_err(),
            "triangle inequality violated"
        );
    }

    #[test]
    fn from_sides_reproduces_the_sides() {
        let rig = Rig3::from_sides(0.37, 0.35, 0.30).unwrap();
        let g = rig.guides_m();
        assert!(((g[1] - g[0]).norm() - 0.37).abs() < 1e-12);
        assert!(((g[2] - g[0]).norm() - 0.35).abs() < 1e-12);
        assert!(((g[2] - g[1]).norm() - 0.30).abs() < 1e-12);
        assert!(g[2].y > 0.0);
    }

    #[test]
    fn noisy_lengths_in_the_plane_clamp_instead_of_nan() {
        let rig = paper_rig();
        let mut l = rig.inverse(&Vec3::new(0.1, 0.1, 0.0));
        l[0] -= 1e-3;
        let s = rig.forward(&l);
        assert!(s.clamped);
        assert!(s.position_m.iter().all(|c| c.is_finite()));
        assert_eq!(s.position_m.z, 0.0);
    }

    #[test]
    fn tensions_reproduce_the_force() {
        let rig = paper_rig();
        let p = Vec3::new(0.18, 0.12, 0.30);
        let f = Vec3::new(0.0, 0.0, -3.0);
        let t = rig.tensions_for_force(&p, &f).unwrap();
        assert!(
            t.iter().all(|&ti| ti > 0.0),
            "a pull towards the frame needs only positive tensions"
        );
        let back = rig.force_matrix(&p) * Vec3::new(t[0], t[1], t[2]);
        assert!((back - f).norm() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 512, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
        #[test]
        fn kinematics_round_trip(x in -0.1f64..0.5, y in -0.1f64..0.45, z in 0.02f64..0.6) {
            let rig = paper_rig();
            let p = Vec3::new(x, y, z);
            let s = rig.forward(&rig.inverse(&p));
            prop_assert!(!s.clamped);
            prop_assert!((s.position_m - p).norm() < 1e-9, "{:?} vs {:?}", s.position_m, p);
        }

        #[test]
        fn forward_never_gives_nan(l0 in -2.0f64..2.0, l1 in -2.0f64..2.0, l2 in -2.0f64..2.0, scale in prop_oneof![Just(1.0), Just(1e-200), Just(1e200)]) {
            let s = paper_rig().forward(&[l0 * scale, l1 * scale, l2 * scale]);
            prop_assert!(s.position_m.iter().all(|c| c.is_finite()));
            prop_assert!(s.position_m.z >= 0.0);
        }

        #[test]
        fn noisy_lengths_near_the_plane_clamp_and_say_so(x in 0.0f64..0.37, y in 0.0f64..0.3, noise in -2e-3f64..2e-3) {
            let rig = paper_rig();
            let mut l = rig.inverse(&Vec3::new(x, y, 1e-4));
            l[0] += noise;
            let s = rig.forward(&l);
            prop_assert!(s.position_m.iter().all(|c| c.is_finite()));
            if s.clamped {
                prop_assert_eq!(s.position_m.z, 0.0);
            } else {
                prop_assert!(s.position_m.z >= 0.0);
            }
        }

        #[test]
        fn velocity_map_matches_finite_difference(x in 0.0f64..0.4, y in 0.0f64..0.3, z in 0.1f64..0.5,
                                                   vx in -0.5f64..0.5, vy in -0.5f64..0.5, vz in -0.5f64..0.5) {
            let rig = paper_rig();
            let p = Vec3::new(x, y, z);
            let v = Vec3::new(vx, vy, vz);
            let h = 1e-7;
            let l0 = rig.inverse(&p);
            let l1 = rig.inverse(&(p + v * h));
            let rates = [(l1[0] - l0[0]) / h, (l1[1] - l0[1]) / h, (l1[2] - l0[2]) / h];
            let back = rig.velocity_from_rates(&p, &rates).unwrap();
            prop_assert!((back - v).norm() < 1e-4 * (1.0 + v.norm()));
        }
    }
}
