//! The workspace a rig can serve: its definition ([`WorkspaceSpec`]), the test of one point
//! ([`serves_point`]) and the sampling on a grid ([`workspace`]).

use nalgebra::Matrix3;

use crate::kinematics::Rig3;
use crate::Vec3;
use crate::WIREMAN_WIRES;

/// What "the workspace the rig can serve" means: the points in front of the frame
/// (`z_min_m <= z <= z_max_m`, above the guide triangle's bounding box) where
///
/// 1. the wires can pull the thimble towards the frame (`-z`) with `force_n` while every tension
///    stays within `[t_min_n, t_max_n]` (the tensions `t = V⁻¹ f` of eq. 5 are `>= 0`, and
///    `t_min_n + max t <= t_max_n`), and
/// 2. the force map `V` of eq. 4 is well conditioned: `‖V‖_F · ‖V⁻¹‖_F <= max_condition`
///    (the Frobenius condition number, an upper bound of the 2-norm one), so a small length error
///    does not become a large force error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkspaceSpec {
    /// Force the wires must render towards the frame, N.
    pub force_n: f64,
    /// Minimum wire tension, N.
    pub t_min_n: f64,
    /// Maximum wire tension, N.
    pub t_max_n: f64,
    /// Largest Frobenius condition number of `V` accepted.
    pub max_condition: f64,
    /// Nearest plane of the workspace in front of the frame, metres.
    pub z_min_m: f64,
    /// Farthest plane, metres.
    pub z_max_m: f64,
    /// Grid step of the sampling, metres.
    pub step_m: f64,
}

/// The workspace of a rig, sampled on a grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Workspace {
    /// Volume of the served points, m³ (served grid cells times the cell volume).
    pub volume_m3: f64,
    /// Number of served grid points.
    pub points: u32,
    /// Lower corner of the served points' bounding box, metres.
    pub min_m: [f64; 3],
    /// Upper corner, metres.
    pub max_m: [f64; 3],
    /// The longest each wire gets anywhere in the workspace, metres: a wire must be usable at
    /// least this long.
    pub required_length_m: [f64; WIREMAN_WIRES],
}

/// Whether a point is served (see [`WorkspaceSpec`]).
pub fn serves_point(rig: &Rig3, spec: &WorkspaceSpec, p: &Vec3) -> bool {
    let v: Matrix3<f64> = rig.force_matrix(p);
    let Some(v_inv) = v.try_inverse() else {
        return false;
    };
    let condition = v.norm() * v_inv.norm();
    if !(condition.is_finite() && condition <= spec.max_condition) {
        return false;
    }
    let t = v_inv * Vec3::new(0.0, 0.0, -spec.force_n);
    t.iter()
        .all(|&ti| ti >= 0.0 && spec.t_min_n + ti <= spec.t_max_n)
}

/// Sample the workspace of `rig` (bounded loops: at most 200 steps per axis).
pub fn workspace(rig: &Rig3, spec: &WorkspaceSpec) -> Workspace {
    let g = rig.guides_m();
    let (mut lo, mut hi) = (g[0], g[0]);
    for gi in g.iter() {
        lo = lo.inf(gi);
        hi = hi.sup(gi);
    }
    let step = spec.step_m.max(1e-3);
    let count = |a: f64, b: f64| -> u32 {
        let n = nalgebra::ComplexField::floor((b - a) / step);
        if n.is_finite() && n >= 0.0 {
            (n as u32 + 1).min(200)
        } else {
            0
        }
    };
    let (nx, ny, nz) = (
        count(lo.x, hi.x),
        count(lo.y, hi.y),
        count(spec.z_min_m, spec.z_max_m),
    );
    let mut out = Workspace {
        volume_m3: 0.0,
        points: 0,
        min_m: [f64::INFINITY; 3],
        max_m: [f64::NEG_INFINITY; 3],
        required_length_m: [0.0; WIREMAN_WIRES],
    };
    for ix in 0..nx {
        for iy in 0..ny {
            for iz in 0..nz {
                let p = Vec3::new(
                    lo.x + ix as f64 * step,
                    lo.y + iy as f64 * step,
                    spec.z_min_m + iz as f64 * step,
                );
                if !serves_point(rig, spec, &p) {
                    continue;
                }
                out.points += 1;
                for k in 0..3 {
                    out.min_m[k] = out.min_m[k].min(p[k]);
                    out.max_m[k] = out.max_m[k].max(p[k]);
                }
                let l = rig.inverse(&p);
                for i in 0..WIREMAN_WIRES {
                    out.required_length_m[i] = out.required_length_m[i].max(l[i]);
                }
            }
        }
    }
    out.volume_m3 = out.points as f64 * step * step * step;
    if out.points == 0 {
        out.min_m = [0.0; 3];
        out.max_m = [0.0; 3];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn workspace_of_the_papers_frame_is_in_front_of_the_triangle() {
        let rig = Rig3::from_sides(0.37, 0.35, 0.35).unwrap();
        let spec = WorkspaceSpec {
            force_n: 3.0,
            t_min_n: 0.3,
            t_max_n: 15.0,
            max_condition: 20.0,
            z_min_m: 0.1,
            z_max_m: 0.6,
            step_m: 0.02,
        };
        let ws = workspace(&rig, &spec);
        assert!(ws.points > 100, "{ws:?}");
        assert!(ws.min_m[2] >= 0.1 && ws.max_m[2] <= 0.6);
        // A point right in front of the centroid is served; one outside the triangle's prism is not.
        let c = (rig.guides_m()[0] + rig.guides_m()[1] + rig.guides_m()[2]) / 3.0;
        assert!(serves_point(&rig, &spec, &(c + Vec3::new(0.0, 0.0, 0.3))));
        assert!(!serves_point(&rig, &spec, &Vec3::new(-0.2, -0.2, 0.3)));
        for l in ws.required_length_m {
            assert!(l > 0.3 && l < 1.0, "{l}");
        }
    }
}
