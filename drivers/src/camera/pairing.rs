//! Pairing frames of two free-running cameras by capture time: a pair is two frames whose
//! timestamps differ by at most the tolerance; otherwise the older frame is dropped.

/// What to do with the two oldest frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairDecision {
    /// They form a pair.
    Pair,
    /// The left frame is too old: drop it and take the next left frame.
    DropLeft,
    /// The right frame is too old: drop it and take the next right frame.
    DropRight,
}

/// Decide on two frames stamped `left_ns` and `right_ns`.
pub fn decide(left_ns: u64, right_ns: u64, tolerance_ns: u64) -> PairDecision {
    if left_ns.abs_diff(right_ns) <= tolerance_ns {
        PairDecision::Pair
    } else if left_ns < right_ns {
        PairDecision::DropLeft
    } else {
        PairDecision::DropRight
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pair two timestamp streams the way a capture loop does.
    fn pair_streams(left: &[u64], right: &[u64], tol: u64) -> Vec<(u64, u64)> {
        let (mut i, mut j, mut out) = (0, 0, vec![]);
        while i < left.len() && j < right.len() {
            match decide(left[i], right[j], tol) {
                PairDecision::Pair => {
                    out.push((left[i], right[j]));
                    i += 1;
                    j += 1;
                }
                PairDecision::DropLeft => i += 1,
                PairDecision::DropRight => j += 1,
            }
        }
        out
    }

    #[test]
    fn pairs_within_tolerance_and_drops_the_unmatched() {
        // 30 fps cameras, the right one 4 ms late; a right frame is lost at 66 ms.
        let left = [0, 33, 66, 100, 133];
        let right = [4, 37, 104, 137];
        assert_eq!(
            pair_streams(&left, &right, 5),
            vec![(0, 4), (33, 37), (100, 104), (133, 137)]
        );
        // A camera that started late: its first frames have no partner.
        assert_eq!(pair_streams(&[0, 33, 66], &[60, 93], 8), vec![(66, 60)]);
        assert_eq!(decide(10, 10, 0), PairDecision::Pair);
        assert_eq!(decide(100, 10, 5), PairDecision::DropRight);
    }
}
