//! Segments and scenes shared by the matcher's tests.

use crate::segments::Segment;

pub(super) fn seg(x0: f32, y0: f32, x1: f32, y1: f32, polarity: i8, sides: [f32; 2]) -> Segment {
    let (mut s, mut e) = ([x0, y0], [x1, y1]);
    if e[1] < s[1] {
        std::mem::swap(&mut s, &mut e);
    }
    let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
    let mut angle = dy.atan2(dx);
    if angle >= std::f32::consts::PI {
        angle -= std::f32::consts::PI;
    }
    Segment {
        start: s,
        end: e,
        length_px: (dx * dx + dy * dy).sqrt(),
        angle_rad: angle,
        polarity,
        contrast: 100.0,
        side_intensity: sides,
        chain: 0,
    }
}

/// A synthetic scene: a fan of segments on a fronto-parallel plane at disparity `d`.
pub(super) fn scene(d: f32) -> (Vec<Segment>, Vec<Segment>) {
    let mut left = Vec::new();
    let mut right = Vec::new();
    for k in 0..12 {
        let x = 80.0 + 17.0 * k as f32;
        let y = 40.0 + 6.0 * (k % 3) as f32;
        let slant = 0.15 * (k % 4) as f32;
        let sides = [40.0 + 12.0 * k as f32, 200.0 - 9.0 * k as f32];
        let pol = if k % 2 == 0 { 1 } else { -1 };
        let l = seg(
            x,
            y,
            x + 40.0 * slant,
            y + 40.0 + 3.0 * k as f32,
            pol,
            sides,
        );
        let mut r = l;
        r.start[0] -= d;
        r.end[0] -= d;
        left.push(l);
        right.push(r);
    }
    (left, right)
}
