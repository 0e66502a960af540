//! Force fields added to the contact force (paper section 5, algorithms F1 and F2, and the
//! free-space field).
//!
//! With a field the device renders `f'_e = f_e + f_c` instead of `f_e`: the user feels the
//! surface as a variation of a constant pull, like the weight of an object, and forces outside the
//! wire cone become renderable (paper Fig. 16).

use nalgebra::SVector;

use crate::algorithm::{Algorithm, FieldRule};
use crate::wire_map::WireMap;

/// A force field of constant magnitude.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceField<const N: usize = 3> {
    /// `|f_c|`, newtons (0 = no field: the paper's P1 and P2).
    pub magnitude_n: f64,
    /// The fixed direction used by P1, P2 and F1 (normalised on use; zero or non-finite falls
    /// back to the bisector). Default `-z`: towards the guide frame, along the body, which lies
    /// inside the wire cone wherever the thimble is over the guide polygon.
    pub direction: SVector<f64, N>,
}

impl<const N: usize> ForceField<N> {
    /// No field.
    pub fn none() -> ForceField<N> {
        ForceField::towards_frame(0.0)
    }

    /// A field of `magnitude_n` newtons along `-z` (the last coordinate: `z` in 3D, `z` of the
    /// planar `[x, z]`), i.e. towards the guides.
    pub fn towards_frame(magnitude_n: f64) -> ForceField<N> {
        let mut direction = SVector::<f64, N>::zeros();
        direction[N - 1] = -1.0;
        ForceField {
            magnitude_n,
            direction,
        }
    }
}

impl<const N: usize> Default for ForceField<N> {
    fn default() -> Self {
        ForceField::none()
    }
}

/// The field force `f_c` the algorithm adds at the position described by `map`, newtons.
/// Zero when the magnitude is zero or not finite.
pub fn field_force<const N: usize>(
    algorithm: Algorithm,
    field: &ForceField<N>,
    map: &WireMap<N>,
) -> SVector<f64, N> {
    let m = field.magnitude_n;
    if !(m.is_finite() && m != 0.0) {
        return SVector::zeros();
    }
    let direction = match algorithm.field_rule() {
        FieldRule::Bisector => map.bisector(),
        FieldRule::Constant => {
            let norm = field.direction.norm();
            if norm > 1e-12 && norm.is_finite() {
                field.direction / norm
            } else {
                map.bisector()
            }
        }
    };
    direction * m
}

/// The gravity-like free-space field: along the bisector, with the given magnitude raised where
/// needed so that every wire carries at least `t_min` (`t = J^T f >= t_min` without clamping).
pub fn free_space_force<const N: usize>(
    magnitude_n: f64,
    t_min_n: f64,
    map: &WireMap<N>,
) -> SVector<f64, N> {
    let d = map.bisector();
    let per_newton = map.tensions(&d);
    let mut needed: f64 = 0.0;
    for t in per_newton {
        if t > 1e-9 {
            needed = needed.max(t_min_n / t);
        }
    }
    let m = if magnitude_n.is_finite() {
        magnitude_n.max(needed)
    } else {
        needed
    };
    d * m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planar::{RigPlanar, Vec2};

    #[test]
    fn fields_point_where_the_paper_says() {
        let rig = RigPlanar::paper_prototype();
        // Off-centre the bisector tilts, the constant field does not.
        let map = rig.wire_map(&Vec2::new(0.1, 0.2)).unwrap();
        let field = ForceField::<2>::towards_frame(2.0);
        let f1 = field_force(Algorithm::F1, &field, &map);
        assert!((f1 - Vec2::new(0.0, -2.0)).norm() < 1e-12);
        let f2 = field_force(Algorithm::F2, &field, &map);
        assert!((f2.norm() - 2.0).abs() < 1e-12);
        let u0 = map.pull_direction(0);
        let u1 = map.pull_direction(1);
        assert!((f2.dot(&u0) - f2.dot(&u1)).abs() < 1e-12, "bisector");
        assert_eq!(
            field_force(Algorithm::P1, &ForceField::none(), &map),
            Vec2::zeros()
        );
    }

    #[test]
    fn free_space_field_keeps_every_wire_taut() {
        let rig = RigPlanar::paper_prototype();
        for p in [
            Vec2::new(0.26, 0.26),
            Vec2::new(-0.2, 0.1),
            Vec2::new(0.7, 0.5),
        ] {
            let map = rig.wire_map(&p).unwrap();
            let f = free_space_force(0.1, 0.4, &map);
            let t = map.tensions(&f);
            assert!(t.iter().all(|&x| x >= 0.4 - 1e-12), "{p:?}: {t:?}");
            assert!(f.norm() >= 0.1);
        }
    }
}
