//! Plane geometry of segments shared by the stages: extents, distances, angles and closest
//! points.

use crate::segments::Segment;

/// Row extent `[start, end]` and column extent `[min, max]` of a segment, pixels.
#[derive(Debug, Clone, Copy)]
pub(super) struct Extent {
    pub(super) rows: [f32; 2],
    pub(super) columns: [f32; 2],
}

impl Extent {
    /// The extents of `s`.
    pub(super) fn of(s: &Segment) -> Self {
        let (x0, x1) = min_max(s.start[0], s.end[0]);
        Self {
            rows: [s.start[1], s.end[1]],
            columns: [x0, x1],
        }
    }

    /// Squared distance between this box and `other` (0 when they overlap).
    pub(super) fn gap_squared(&self, other: &Extent) -> f32 {
        let gap_x = (self.columns[0] - other.columns[1])
            .max(other.columns[0] - self.columns[1])
            .max(0.0);
        let gap_y = (self.rows[0] - other.rows[1])
            .max(other.rows[0] - self.rows[1])
            .max(0.0);
        gap_x * gap_x + gap_y * gap_y
    }
}

/// Whether two row intervals overlap by more than one pixel.
pub(super) fn rows_overlap(a: [f32; 2], b: [f32; 2]) -> bool {
    a[1].min(b[1]) - a[0].max(b[0]) > 1.0
}

/// Distance of point `p` from the supporting line of `s`, pixels.
pub(super) fn line_distance(s: &Segment, p: [f32; 2]) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let (px, py) = (p[0] - s.start[0], p[1] - s.start[1]);
    (dx * py - dy * px).abs() / s.length_px.max(1e-3)
}

/// The two values in increasing order.
pub(super) fn min_max(a: f32, b: f32) -> (f32, f32) {
    if a < b {
        (a, b)
    } else {
        (b, a)
    }
}

/// Angle between the directions of two segments, radians in `[0, pi/2]`.
pub(super) fn angle_difference(a: &Segment, b: &Segment) -> f32 {
    let difference = (a.angle_rad - b.angle_rad).abs();
    if difference > std::f32::consts::FRAC_PI_2 {
        std::f32::consts::PI - difference
    } else {
        difference
    }
}

/// Distance between two segments and the parameters (0 at `start`, 1 at `end`) of the closest
/// points.
pub(super) fn segment_distance(a: &Segment, b: &Segment) -> (f32, f32, f32) {
    let mut best = (f32::INFINITY, 0.0, 0.0);
    // Segments that do not cross are closest at an endpoint of one of them.
    for (p, on_a, t_fixed) in [
        (a.start, false, 0.0),
        (a.end, false, 1.0),
        (b.start, true, 0.0),
        (b.end, true, 1.0),
    ] {
        let s = if on_a { a } else { b };
        let t = project_param(s, p);
        let q = lerp(s, t);
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if d < best.0 {
            best = if on_a {
                (d, t, t_fixed)
            } else {
                (d, t_fixed, t)
            };
        }
    }
    best
}

/// Parameter (0 at `start`, 1 at `end`) of the point of `s` closest to `p`.
pub(super) fn project_param(s: &Segment, p: [f32; 2]) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let len2 = dx * dx + dy * dy;
    if len2 < 1e-9 {
        return 0.0;
    }
    (((p[0] - s.start[0]) * dx + (p[1] - s.start[1]) * dy) / len2).clamp(0.0, 1.0)
}

/// The point at parameter `t` along `s`.
pub(super) fn lerp(s: &Segment, t: f32) -> [f32; 2] {
    [
        s.start[0] + t * (s.end[0] - s.start[0]),
        s.start[1] + t * (s.end[1] - s.start[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matching::test_support::seg;

    #[test]
    fn closest_points_of_two_segments() {
        let a = seg(0.0, 0.0, 0.0, 10.0, 1, [0.0, 0.0]);
        let b = seg(3.0, 12.0, 3.0, 20.0, 1, [0.0, 0.0]);
        let (d, ta, tb) = segment_distance(&a, &b);
        assert!((d - (9.0f32 + 4.0).sqrt()).abs() < 1e-5);
        assert_eq!((ta, tb), (1.0, 0.0));
    }
}
