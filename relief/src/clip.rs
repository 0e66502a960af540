//! Clipping a segment to a rectangle of the explorable area, shared by the builder, the model's
//! motion queries and the local updates.

/// Clip the segment `a + s (b - a)`, `s` in `[0, 1]`, to a rectangle `[x0, y0, x1, y1]`
/// (Liang–Barsky); the kept parameter range.
pub(crate) fn clip_to_rect(a: [f64; 2], b: [f64; 2], rect: [f64; 4]) -> Option<(f64, f64)> {
    let d = [b[0] - a[0], b[1] - a[1]];
    let (mut s0, mut s1) = (0.0f64, 1.0f64);
    for (p, q) in [
        (-d[0], a[0] - rect[0]),
        (d[0], rect[2] - a[0]),
        (-d[1], a[1] - rect[1]),
        (d[1], rect[3] - a[1]),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                s0 = s0.max(r);
            } else {
                s1 = s1.min(r);
            }
        }
    }
    (s0 <= s1).then_some((s0, s1))
}
