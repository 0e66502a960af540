//! Geometry the experiments share: the regions of the planar device's force space (paper
//! Fig. 12), the operator's scripted paths along a profile, and how well a recorded path follows
//! a profile.

use videt_control::planar::Vec2;
use videt_control::{PlanarDevice, Profile, Vec3, WireDevice};
use videt_sim::Waypoint;

use crate::closed_loop::Sample;

/// The regions of the planar device's force space at a position (paper Fig. 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// Inside the cone of the wires' pulls: a force along it is rendered exactly.
    A,
    /// Beside the cone, neither in it nor opposite it.
    B,
    /// Opposite the cone: a force along it would need every wire to push.
    C,
}

impl Region {
    /// The region's letter.
    pub fn name(self) -> &'static str {
        match self {
            Region::A => "A",
            Region::B => "B",
            Region::C => "C",
        }
    }
}

/// The region of direction `direction` (a force, or a surface normal: `f_e` is along `n`) at
/// `position_m` of the planar device. Directions on a boundary count as inside A or C.
pub fn planar_region(device: &PlanarDevice, position_m: &Vec3, direction: &Vec3) -> Region {
    let u0 = device.pull_direction(position_m, 0);
    let u1 = device.pull_direction(position_m, 1);
    // direction = a u0 + b u1 in the x-z plane.
    let det = u0.x * u1.z - u0.z * u1.x;
    if det.abs() < 1e-12 {
        return Region::B;
    }
    let a = (direction.x * u1.z - direction.z * u1.x) / det;
    let b = (u0.x * direction.z - u0.z * direction.x) / det;
    let eps = 1e-9 * direction.norm();
    if a >= -eps && b >= -eps {
        Region::A
    } else if a <= eps && b <= eps {
        Region::C
    } else {
        Region::B
    }
}

/// A point of the x-z plane at `y`.
pub fn xz(p: &Vec2, y: f64) -> Vec3 {
    Vec3::new(p.x, y, p.y)
}

/// Waypoints along `points` at `speed_m_s`, the first at `start_s`; returns them and the time
/// of the last.
pub fn waypoints_along(points: &[Vec3], start_s: f64, speed_m_s: f64) -> (Vec<Waypoint>, f64) {
    let mut t = start_s;
    let mut out = Vec::with_capacity(points.len());
    for (k, p) in points.iter().enumerate() {
        if k > 0 {
            t += (p - points[k - 1]).norm() / speed_m_s;
        }
        out.push(Waypoint {
            time_s: t,
            target_m: *p,
        });
    }
    (out, t)
}

/// Follow-up of a recorded path against a profile over a window of samples.
#[derive(Debug, Clone, PartialEq)]
pub struct PathStats {
    /// Samples in the window.
    pub samples: usize,
    /// Share of them in contact.
    pub contact_fraction: f64,
    /// Largest distance of the thimble from the profile, either side, metres.
    pub max_distance_m: f64,
    /// RMS distance of the thimble from the profile, either side, metres.
    pub rms_distance_m: f64,
    /// Largest distance while out of contact (how far the thimble left the surface), metres.
    pub max_gap_m: f64,
    /// Mean penetration depth in contact, metres.
    pub mean_depth_m: f64,
    /// 95th percentile of the penetration depth in contact, metres.
    pub p95_depth_m: f64,
    /// Largest penetration depth in contact, metres.
    pub max_depth_m: f64,
    /// Per segment of the profile, the share of its length the thimble touched (the nearest
    /// point of the contacts, in 20 bins per segment).
    pub segment_coverage: Vec<f64>,
}

/// Bins per segment for [`PathStats::segment_coverage`].
const COVERAGE_BINS: usize = 20;

/// How the samples `window` follow `profile` (distances from the sensed positions).
pub fn path_stats<'a, const N: usize, const CAP: usize>(
    profile: &Profile<CAP>,
    window: impl Iterator<Item = &'a Sample<N>>,
) -> PathStats {
    let segments = profile.segment_count();
    let mut bins = vec![[false; COVERAGE_BINS]; segments];
    let (mut n, mut contacts) = (0usize, 0usize);
    let (mut max_d, mut sum_sq, mut max_gap) = (0.0f64, 0.0f64, 0.0f64);
    let mut depths = Vec::new();
    for s in window {
        n += 1;
        let p = Vec2::new(s.position_m.x, s.position_m.z);
        let Some(near) = profile.nearest(&p) else {
            continue;
        };
        let d = near.signed_distance_m.abs();
        max_d = max_d.max(d);
        sum_sq += d * d;
        if s.in_contact {
            contacts += 1;
            depths.push(s.depth_m);
            // The touched point of every segment within a millimetre of the nearest one (a
            // vertex touches both of its segments).
            for (i, seg) in bins.iter_mut().enumerate() {
                let (t, dist) = profile.project_on_segment(i, &near.point_m);
                if dist < 1e-3 {
                    let bin = ((t * COVERAGE_BINS as f64) as usize).min(COVERAGE_BINS - 1);
                    seg[bin] = true;
                }
            }
        } else {
            max_gap = max_gap.max(d);
        }
    }
    depths.sort_by(f64::total_cmp);
    let mean_depth_m = if depths.is_empty() {
        0.0
    } else {
        depths.iter().sum::<f64>() / depths.len() as f64
    };
    PathStats {
        samples: n,
        contact_fraction: if n == 0 {
            0.0
        } else {
            contacts as f64 / n as f64
        },
        max_distance_m: max_d,
        rms_distance_m: if n == 0 {
            0.0
        } else {
            (sum_sq / n as f64).sqrt()
        },
        max_gap_m: max_gap,
        mean_depth_m,
        p95_depth_m: percentile(&depths, 0.95),
        max_depth_m: depths.last().copied().unwrap_or(0.0),
        segment_coverage: bins
            .iter()
            .map(|b| b.iter().filter(|&&x| x).count() as f64 / COVERAGE_BINS as f64)
            .collect(),
    }
}

/// The `q` quantile of sorted values (0 when empty).
pub fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return 0.0;
    }
    let k = ((sorted.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    sorted[k]
}

/// Mean of the values (0 when empty).
pub fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for v in values {
        sum += v;
        n += 1;
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_of_the_prototype_at_the_centre() {
        let d = PlanarDevice::paper_prototype();
        let p = Vec3::new(0.26, 0.0, 0.26);
        assert_eq!(planar_region(&d, &p, &-Vec3::z()), Region::A);
        assert_eq!(planar_region(&d, &p, &Vec3::z()), Region::C);
        assert_eq!(planar_region(&d, &p, &Vec3::x()), Region::B);
        assert_eq!(planar_region(&d, &p, &-Vec3::x()), Region::B);
        // Just inside the 45-degree wires.
        assert_eq!(
            planar_region(&d, &p, &Vec3::new(0.7, 0.0, -0.72)),
            Region::A
        );
        assert_eq!(
            planar_region(&d, &p, &Vec3::new(0.72, 0.0, -0.7)),
            Region::B
        );
    }

    #[test]
    fn waypoints_are_timed_by_distance() {
        let pts = [
            Vec3::zeros(),
            Vec3::new(0.1, 0.0, 0.0),
            Vec3::new(0.1, 0.0, 0.2),
        ];
        let (w, end) = waypoints_along(&pts, 1.0, 0.1);
        assert_eq!(w.len(), 3);
        assert!((w[1].time_s - 2.0).abs() < 1e-12);
        assert!((end - 4.0).abs() < 1e-12);
    }
}
