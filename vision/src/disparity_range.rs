//! The disparity search range, chosen from the pair itself.
//!
//! A fixed bound (64 px) silently misses every match beyond it on a larger image or a closer
//! scene, and a bound of the whole image width lets far more right segments compete for each
//! left one (more work, more ambiguity). The range is instead measured: a first pass matches
//! the pair searching every disparity the image allows, and the bound is the high quantile of
//! the disparities it found (a few wrong matches at large disparity do not move it) with a
//! margin for the part of the scene that pass did not reach.

use crate::error::VisionError;
use crate::gray::GrayView;
use crate::pipeline::{StereoPipeline, VisionParams};

/// Quantile of the first pass's disparities taken as the scene's largest (the rest is allowed
/// to be wrong matches).
pub const RANGE_QUANTILE: f32 = 0.98;
/// The bound is the quantile times this...
pub const RANGE_MARGIN_RATIO: f32 = 1.25;
/// ... plus this many pixels.
pub const RANGE_MARGIN_PX: f32 = 8.0;
/// Fewest back-projectable (not nearly horizontal) first-pass matches to trust their quantile;
/// with fewer, the whole width is searched.
pub const MIN_MATCHES_FOR_RANGE: usize = 20;
/// The bound never goes below this, pixels (a far scene still gets a usable window).
pub const MIN_RANGE_PX: f32 = 16.0;

/// How the disparity bound was chosen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisparityRange {
    /// The bound to search with, pixels.
    pub max_px: f32,
    /// The range the first pass searched, pixels.
    pub searched_px: f32,
    /// Back-projectable matches the first pass found.
    pub first_pass_matches: usize,
    /// Their [`RANGE_QUANTILE`] disparity, pixels (`None` when too few to trust).
    pub quantile_px: Option<f32>,
}

impl DisparityRange {
    /// One line for a report.
    pub fn describe(&self) -> String {
        match self.quantile_px {
            Some(q) => format!(
                "max disparity {:.0} px (automatic: {:.0}th percentile {:.1} px of {} matches \
                 found searching 0..{:.0} px, x{} + {} px)",
                self.max_px,
                100.0 * RANGE_QUANTILE,
                q,
                self.first_pass_matches,
                self.searched_px,
                RANGE_MARGIN_RATIO,
                RANGE_MARGIN_PX
            ),
            None => format!(
                "max disparity {:.0} px (automatic: only {} matches searching 0..{:.0} px, \
                 fewer than {MIN_MATCHES_FOR_RANGE}: the whole range is kept)",
                self.max_px, self.first_pass_matches, self.searched_px
            ),
        }
    }
}

/// The bound for the disparities `disparities` (of back-projectable matches) found searching up
/// to `searched_px`. Pure: the rule of [`choose_max_disparity`].
pub fn bound_from_disparities(mut disparities: Vec<f32>, searched_px: f32) -> DisparityRange {
    // NaN from a degenerate segment must not sort.
    disparities.retain(|d| d.is_finite());
    let n = disparities.len();
    if n < MIN_MATCHES_FOR_RANGE {
        return DisparityRange {
            max_px: searched_px,
            searched_px,
            first_pass_matches: n,
            quantile_px: None,
        };
    }
    disparities.sort_unstable_by(f32::total_cmp);
    let rank = ((n - 1) as f32 * RANGE_QUANTILE).round() as usize;
    let q = disparities[rank.min(n - 1)].max(0.0);
    let max_px = (q * RANGE_MARGIN_RATIO + RANGE_MARGIN_PX)
        .ceil()
        .clamp(MIN_RANGE_PX.min(searched_px), searched_px);
    DisparityRange {
        max_px,
        searched_px,
        first_pass_matches: n,
        quantile_px: Some(q),
    }
}

/// Chooses the largest disparity to search on the pair `left`, `right` (rectified): a first
/// pass with `params` searches every disparity up to the image width (at most 4096 px), and
/// the bound is the [`RANGE_QUANTILE`] of its back-projectable matches' disparities (mean of
/// the two endpoints) times [`RANGE_MARGIN_RATIO`] plus [`RANGE_MARGIN_PX`], within
/// [`MIN_RANGE_PX`]..the width. `params.matching.disparity_max_px` is ignored.
pub fn choose_max_disparity(
    pipeline: &mut StereoPipeline,
    left: &GrayView<'_>,
    right: &GrayView<'_>,
    params: &VisionParams,
) -> Result<DisparityRange, VisionError> {
    let searched_px = ((left.width().saturating_sub(1)) as f32)
        .clamp(params.matching.disparity_min_px + 1.0, 4096.0);
    let mut wide = *params;
    wide.matching.disparity_max_px = searched_px;
    let output = pipeline.run(left, right, None, &wide)?;
    let disparities: Vec<f32> = output
        .matches
        .iter()
        .filter(|m| !m.nearly_horizontal)
        .map(|m| 0.5 * (m.disparity_px[0] + m.disparity_px[1]))
        .collect();
    Ok(bound_from_disparities(disparities, searched_px))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_bound_is_the_high_quantile_with_its_margin_and_ignores_a_few_outliers() {
        // 100 matches at 40..50 px and two wrong ones far out.
        let mut d: Vec<f32> = (0..100).map(|i| 40.0 + (i % 11) as f32).collect();
        d.extend([300.0, 410.0, f32::NAN]);
        let r = bound_from_disparities(d, 639.0);
        assert_eq!(r.first_pass_matches, 102);
        let q = r.quantile_px.unwrap();
        assert!((49.0..=50.0).contains(&q), "{q}");
        assert_eq!(r.max_px, (q * RANGE_MARGIN_RATIO + RANGE_MARGIN_PX).ceil());
        assert!(r.describe().contains("automatic"), "{}", r.describe());
    }

    #[test]
    fn too_few_matches_keep_the_whole_range_and_the_bound_stays_inside_it() {
        let r = bound_from_disparities(vec![10.0f32; MIN_MATCHES_FOR_RANGE - 1], 300.0);
        assert_eq!((r.max_px, r.quantile_px), (300.0, None));
        assert!(r.describe().contains("fewer than"), "{}", r.describe());
        assert_eq!(
            bound_from_disparities(vec![1.0f32; 50], 300.0).max_px,
            MIN_RANGE_PX
        );
        assert_eq!(
            bound_from_disparities(vec![290.0f32; 50], 300.0).max_px,
            300.0
        );
    }
}
