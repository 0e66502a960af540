//! The direction of the contact force against the wires: the paper's sub-regions A, B and C of
//! the force directions at the thimble, the wall the Z-width is judged on in each, and the
//! surface normals the stiffness sweep tilts by their angle from the frame's axis.

use serde::Serialize;
use videt_config::Config;
use videt_sim::Vec3;

/// The paper's sub-regions of the force directions (Figs 10, 12), for the 3-wire device: where
/// the wires can make the contact force `f_e ∥ n` with non-negative tensions (A), where they
/// cannot but some wire still pulls along `n` (B), and where no wire has a component along `n`
/// (C: nothing can push the finger out; the paper's V = 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Region {
    /// All tensions non-negative: the force is made exactly.
    A,
    /// Some tension would be negative, but some wire pulls along `n`.
    B,
    /// No wire pulls along `n`.
    C,
}

impl Region {
    /// The outward normal of the wall the Z-width is judged on in this region, at the bench's
    /// start: A the wall facing the frame (`-z`), B a side wall (`+x`: the guide at `x = 0.37`
    /// still pulls along it), C the wall facing away from the frame (`+z`: no wire pulls along
    /// it, nothing can be rendered).
    pub fn wall_normal(self) -> Vec3 {
        match self {
            Region::A => Vec3::new(0.0, 0.0, -1.0),
            Region::B => Vec3::new(1.0, 0.0, 0.0),
            Region::C => Vec3::new(0.0, 0.0, 1.0),
        }
    }
}

/// The region of the force direction `n` at `position_m` for the configured guides.
pub fn region_of(config: &Config, position_m: Vec3, n: Vec3) -> Region {
    let g = &config.rig.guides_m;
    let cols: [Vec3; 3] = core::array::from_fn(|i| {
        let d = Vec3::new(g[i][0], g[i][1], 0.0) - position_m;
        d / d.norm()
    });
    if cols.iter().all(|u| u.dot(&n) <= 1e-9) {
        return Region::C;
    }
    let u = nalgebra::Matrix3::from_columns(&cols);
    match u.try_inverse() {
        Some(inv) if (inv * n).iter().all(|&t| t >= -1e-9) => Region::A,
        _ => Region::B,
    }
}

/// The unit normal at `polar_deg` from `-z` and `azimuth_deg` around it.
pub(super) fn normal_at(polar_deg: f64, azimuth_deg: f64) -> Vec3 {
    let (t, a) = (polar_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(t.sin() * a.cos(), t.sin() * a.sin(), -t.cos())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::haptic_bench::rig::start_position;

    #[test]
    fn the_frame_axis_is_region_a_and_its_opposite_region_c() {
        let config = Config::default();
        let start = start_position(&config);
        assert_eq!(region_of(&config, start, normal_at(0.0, 0.0)), Region::A);
        assert_eq!(region_of(&config, start, normal_at(180.0, 0.0)), Region::C);
    }
}
