//! The evidence gathered for each match by the checks against wrong matches, and what the
//! checks make of it (see the checks module of the matcher).

use super::params::MatchParams;

/// What speaks for and against a match (see the module documentation of the checks).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MatchEvidence {
    /// Matched neighbours whose disparity at the closest points agrees with the match's
    /// within [`MatchParams::surface_tolerance_px`] plus
    /// [`MatchParams::surface_gradient_limit`] times their distance.
    pub agreeing: u16,
    /// Matched neighbours that do not.
    pub disagreeing: u16,
    /// Support of the best candidate of the same left segment at another disparity (more
    /// than the surface tolerance apart at its middle); `None` when there is no such rival.
    pub rival_support: Option<u32>,
    /// Photometric error of the match, grey levels (`NaN` when the images were not given or
    /// the strips beside the edge could not be sampled).
    pub photometric_error: f32,
    /// Whether completion (rather than propagation) made the match.
    pub completed: bool,
}

impl MatchEvidence {
    /// Confidence in `[0, 1]`: the product of
    /// - the neighbourhood's agreement, `(agreeing + 1) / (agreeing + disagreeing + 2)` (1/2
    ///   for a match without matched neighbours);
    /// - the margin over the best rival, `(s + 1) / (s + r + 2)` with `s` the match's support
    ///   and `r` the rival's (1 without a rival);
    /// - the photometric agreement, `1 - e / (2 limit)` clamped to `[0, 1]`, with `e` the
    ///   photometric error and `limit` the completion photometric limit (1 when unknown).
    pub fn confidence(&self, support: u32, params: &MatchParams) -> f32 {
        let (a, d) = (f32::from(self.agreeing), f32::from(self.disagreeing));
        let neighbourhood = (a + 1.0) / (a + d + 2.0);
        let margin = match self.rival_support {
            None => 1.0,
            Some(r) => (support as f32 + 1.0) / (support as f32 + r as f32 + 2.0),
        };
        let photometric = if self.photometric_error.is_finite() {
            (1.0 - self.photometric_error / (2.0 * params.completion_max_photometric_error))
                .clamp(0.0, 1.0)
        } else {
            1.0
        };
        neighbourhood * margin * photometric
    }

    /// Whether the surface check drops the match (see [`MatchParams::surface_check`]).
    pub fn contradicted(&self, params: &MatchParams) -> bool {
        u32::from(self.disagreeing) >= params.surface_min_disagreeing
            && f32::from(self.agreeing)
                < params.surface_min_agreeing_ratio * f32::from(self.disagreeing)
    }
}
