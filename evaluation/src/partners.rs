//! Which left segments a perfect matcher could match at all: those with a **partner**, a right
//! segment lying where the ground truth says the left edge appears in the right image.
//!
//! A right segment `r` is a partner of a left segment `l` (not nearly horizontal) when they
//! have the same polarity and the left samples on `r`'s rows, moved by their true disparity,
//! land within 1.5 px of `r`'s line for at least half of them, over at least a third of the
//! left segment's length (and 3 samples). The truth is read in the 5x5 window around each
//! sample, as [`judge_match`](super::judge_match) does: an edge on a depth step may belong to
//! either surface. A left segment without a partner is unmatchable by any matcher of these
//! segments: its edge was not detected, or not as a segment, in the right image.

use super::DisparityMap;
use videt_vision::segments::Segment;

/// Whether `r` is a partner of the left segment `l` (see the module documentation).
pub fn is_partner(l: &Segment, r: &Segment, truth: &DisparityMap) -> bool {
    if l.polarity != r.polarity {
        return false;
    }
    let steps = l.length_px.ceil().max(1.0) as usize;
    let (mut on_rows, mut landing) = (0usize, 0usize);
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let x = l.start[0] + t * (l.end[0] - l.start[0]);
        let y = l.start[1] + t * (l.end[1] - l.start[1]);
        if y < r.start[1] || y > r.end[1] {
            continue;
        }
        let Some(xr) = r.x_at_row(y) else {
            continue;
        };
        let (xi, yi) = (x.round() as i64, y.round() as i64);
        let (mut known, mut lands) = (false, false);
        for dy in -2..=2 {
            for dx in -2..=2 {
                if let Some(d) = truth.at(xi + dx, yi + dy) {
                    known = true;
                    lands |= (x - d - xr).abs() <= 1.5;
                }
            }
        }
        if known {
            on_rows += 1;
            landing += usize::from(lands);
        }
    }
    on_rows as f32 >= (steps as f32 / 3.0).max(3.0) && 2 * landing >= on_rows
}

/// How many of the left segments that are not nearly horizontal (more than
/// `horizontal_angle_rad` from horizontal) have a partner among `right`: the most a matcher of
/// these segments could match. Returns `(with a partner, not nearly horizontal)`.
pub fn partnered(
    left: &[Segment],
    right: &[Segment],
    truth: &DisparityMap,
    horizontal_angle_rad: f32,
) -> (usize, usize) {
    // Right segments by upper row, to visit only those that reach a left segment's rows.
    let mut order: Vec<usize> = (0..right.len()).collect();
    order.sort_by(|&a, &b| right[a].start[1].total_cmp(&right[b].start[1]));
    let (mut with, mut total) = (0, 0);
    for l in left
        .iter()
        .filter(|s| !s.is_nearly_horizontal(horizontal_angle_rad))
    {
        total += 1;
        let below = order.partition_point(|&j| right[j].start[1] <= l.end[1]);
        if order[..below]
            .iter()
            .any(|&j| right[j].end[1] >= l.start[1] && is_partner(l, &right[j], truth))
        {
            with += 1;
        }
    }
    (with, total)
}

#[cfg(test)]
mod tests {
    use super::*;

    use super::super::tests::vertical;

    /// A vertical segment at column `x` with `polarity`.
    fn edge(x: f32, polarity: i8) -> Segment {
        Segment {
            polarity,
            ..vertical(x)
        }
    }

    fn truth(d: f32) -> DisparityMap {
        DisparityMap {
            width: 40,
            height: 30,
            values: vec![d; 40 * 30],
        }
    }

    #[test]
    fn a_right_segment_at_the_true_disparity_is_a_partner_and_others_are_not() {
        let t = truth(5.0);
        let l = edge(20.0, 1);
        assert!(is_partner(&l, &edge(15.0, 1), &t));
        assert!(is_partner(&l, &edge(16.2, 1), &t));
        assert!(!is_partner(&l, &edge(12.0, 1), &t));
        assert!(!is_partner(&l, &edge(15.0, -1), &t));
        let (with, total) = partnered(&[l, edge(30.0, 1)], &[edge(15.0, 1)], &t, 0.2);
        assert_eq!((with, total), (1, 2));
    }

    #[test]
    fn without_truth_there_is_no_partner() {
        let unknown = DisparityMap {
            width: 40,
            height: 30,
            values: vec![f32::NAN; 40 * 30],
        };
        assert!(!is_partner(&edge(20.0, 1), &edge(15.0, 1), &unknown));
    }
}
