//! The base triangle from the six side measurements of three windings: the least-squares
//! sides, their residuals and the guide points in the paper's frame.

use super::failure::{Failure, Side};
use crate::kinematics::{Rig3, RigError};
use crate::WIREMAN_WIRES;

/// The measured base triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseTriangle {
    /// Sides `[d01, d02, d12]`, metres (least-squares estimates).
    pub sides_m: [f64; 3],
    /// Residual of each measurement (measurement minus estimate), metres, in measurement order:
    /// winding 0 gives `d01, d02`; winding 1 gives `d01, d12`; winding 2 gives `d02, d12`.
    pub residuals_m: [f64; 6],
    /// The rig in the paper's frame.
    pub rig: Rig3,
}

/// The six side measurements of three windings: `lengths_at_stop_m[i][j]` is wire `j`'s length
/// when winding `i` stopped at ring `i`.
pub fn solve_base_triangle(
    lengths_at_stop_m: &[[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    side_tolerance_m: f64,
) -> Result<BaseTriangle, Failure> {
    let m = lengths_at_stop_m;
    // (side, first measurement, second measurement)
    let pairs = [
        (Side(0, 1), m[0][1], m[1][0]),
        (Side(0, 2), m[0][2], m[2][0]),
        (Side(1, 2), m[1][2], m[2][1]),
    ];
    let mut sides_m = [0.0; 3];
    for (k, (side, a, b)) in pairs.iter().enumerate() {
        if !(a.is_finite() && b.is_finite()) || (a - b).abs() > side_tolerance_m {
            return Err(Failure::SidesDisagree {
                side: *side,
                first_m: *a,
                second_m: *b,
                tolerance_m: side_tolerance_m,
            });
        }
        // Least squares of two equally weighted measurements of one unknown: the mean.
        sides_m[k] = 0.5 * (a + b);
    }
    let residuals_m = [
        m[0][1] - sides_m[0],
        m[0][2] - sides_m[1],
        m[1][0] - sides_m[0],
        m[1][2] - sides_m[2],
        m[2][0] - sides_m[1],
        m[2][1] - sides_m[2],
    ];
    let [d01, d02, d12] = sides_m;
    if d01 + d02 <= d12 || d01 + d12 <= d02 || d02 + d12 <= d01 {
        return Err(Failure::TriangleInequality { sides_m });
    }
    let rig = Rig3::from_sides(d01, d02, d12).map_err(|e| match e {
        RigError::Degenerate { area_m2 } => Failure::DegenerateTriangle {
            area_m2: heron_area_m2(sides_m).max(area_m2),
        },
        _ => Failure::DegenerateTriangle {
            area_m2: heron_area_m2(sides_m),
        },
    })?;
    Ok(BaseTriangle {
        sides_m,
        residuals_m,
        rig,
    })
}

/// Area of a triangle from its sides (Heron), m²; 0 when they do not close.
pub fn heron_area_m2(sides_m: [f64; 3]) -> f64 {
    let [a, b, c] = sides_m;
    let s = 0.5 * (a + b + c);
    let q = s * (s - a) * (s - b) * (s - c);
    if q > 0.0 {
        nalgebra::ComplexField::sqrt(q)
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Vec3;

    fn sides_of(g: &[Vec3; 3]) -> [f64; 3] {
        [
            (g[1] - g[0]).norm(),
            (g[2] - g[0]).norm(),
            (g[2] - g[1]).norm(),
        ]
    }

    fn exact_measurements(g: &[Vec3; 3]) -> [[f64; 3]; 3] {
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (g[j] - g[i]).norm();
            }
        }
        m
    }

    #[test]
    fn exact_measurements_reproduce_the_triangle_in_the_papers_frame() {
        let g = [
            Vec3::new(0.02, -0.01, 0.0),
            Vec3::new(0.41, 0.03, 0.0),
            Vec3::new(0.15, 0.33, 0.0),
        ];
        let t = solve_base_triangle(&exact_measurements(&g), 1e-3).unwrap();
        let truth = sides_of(&g);
        for k in 0..3 {
            assert!((t.sides_m[k] - truth[k]).abs() < 1e-12);
        }
        assert!(t.residuals_m.iter().all(|r| r.abs() < 1e-12));
        let h = t.rig.guides_m();
        assert_eq!(h[0], Vec3::zeros());
        assert_eq!(h[1].y, 0.0);
        assert!(h[2].y > 0.0);
        assert!((sides_of(h)[2] - truth[2]).abs() < 1e-12);
    }

    #[test]
    fn residuals_are_half_the_disagreement() {
        let g = [
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.30, 0.0),
        ];
        let mut m = exact_measurements(&g);
        m[0][1] += 0.4e-3;
        let t = solve_base_triangle(&m, 1e-3).unwrap();
        assert!((t.residuals_m[0] - 0.2e-3).abs() < 1e-12);
        assert!((t.residuals_m[2] + 0.2e-3).abs() < 1e-12);
        m[0][1] += 1.0e-3;
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::SidesDisagree {
                side: Side(0, 1),
                ..
            })
        ));
    }

    #[test]
    fn bad_triangles_have_their_own_errors() {
        // d01 + d02 < d12.
        let m = [[0.0, 0.2, 0.1], [0.2, 0.0, 0.5], [0.1, 0.5, 0.0]];
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::TriangleInequality { .. })
        ));
        // Nearly collinear: closes, but needle-thin.
        let m = [[0.0, 0.2, 0.2], [0.2, 0.0, 0.3999], [0.2, 0.3999, 0.0]];
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::DegenerateTriangle { .. })
        ));
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(43), ..proptest::test_runner::Config::default() })]
        /// Any well-shaped triangle measured with errors below half the tolerance is accepted, its
        /// sides are within the measurement error, and the guides reproduce the sides.
        #[test]
        fn noisy_measurements_of_real_triangles_are_solved(
            x1 in 0.2f64..0.7, y1 in -0.1f64..0.1, x2 in -0.1f64..0.6, y2 in 0.15f64..0.5,
            noise in proptest::array::uniform6(-0.4e-3f64..0.4e-3),
        ) {
            let g = [Vec3::zeros(), Vec3::new(x1, y1, 0.0), Vec3::new(x2, y2, 0.0)];
            proptest::prop_assume!(Rig3::new(g).is_ok());
            let mut m = exact_measurements(&g);
            let slots = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
            for (k, (i, j)) in slots.iter().enumerate() {
                m[*i][*j] += noise[k];
            }
            let t = solve_base_triangle(&m, 1e-3).unwrap();
            let truth = sides_of(&g);
            for k in 0..3 {
                proptest::prop_assert!((t.sides_m[k] - truth[k]).abs() <= 0.4e-3 + 1e-12);
            }
            let solved = sides_of(t.rig.guides_m());
            for k in 0..3 {
                proptest::prop_assert!((solved[k] - t.sides_m[k]).abs() < 1e-9);
            }
            let r: f64 = t.residuals_m.iter().map(|r| r * r).sum();
            proptest::prop_assert!(r.sqrt() <= 1e-3);
        }

        /// Whatever the six numbers, the solver answers (a triangle or a failure) without panic.
        #[test]
        fn arbitrary_measurements_never_panic(m in proptest::array::uniform9(-1.0f64..2.0)) {
            let m = [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]];
            let _ = solve_base_triangle(&m, 2e-3);
        }
    }
}
