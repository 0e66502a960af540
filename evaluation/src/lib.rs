//! # videt-evaluation — what the vision pipeline gives, judged against ground truth
//!
//! Accuracy of segment matches against a ground-truth disparity map (Middlebury convention:
//! a left pixel at `x` matches the right pixel at `x - d`; unknown disparities are absent).
//!
//! How a match is judged: the left segment is sampled every pixel; at each sample the match's
//! disparity (interpolated between its two endpoint disparities) is compared with the ground
//! truth. Samples are skipped where the truth is unknown or occluded (when a right-view map is
//! available, a pixel is occluded if the two maps disagree by more than 1 px). Edges often lie
//! on depth discontinuities, where a one-pixel localisation error jumps between surfaces: if the
//! known truth in the 5x5 window around the sample spans more than 2 px, the sample's error is
//! the distance to the closest truth value in the window (the edge may belong to either
//! surface), otherwise it is the distance to the truth at the sample. A match is **wrong** when
//! the median error of its samples exceeds 1 px; a match with no usable sample is
//! **unevaluated**.
//!
//! Nearly horizontal matches have no measurable disparity along their rows (their endpoints
//! are unstable, which is why they are never back-projected), so for them the correspondence
//! itself is judged: each sample is moved by its true disparity into the right image and must
//! land within 1.5 px of the matched right segment; the match is wrong when fewer than half of
//! the samples that could land (those within the right segment's column extent) do. Their
//! endpoint disparity is judged separately by [`judge_match`] and reported as
//! [`AccuracyReport::horizontal_disparity_wrong`].
//!
//! [`relief`] judges what the matches become: the area of a built bas-relief that departs from
//! the true surface ([`phantom_area`]). [`synthetic`] renders stereo pairs with exact ground truth.

use std::path::Path;

use videt_vision::matching::SegmentMatch;
use videt_vision::segments::Segment;

pub mod partners;
pub mod relief;
pub mod synthetic;

pub use relief::{
    phantom_area, relief_deviation, PhantomArea, ReliefDeviation, ReliefEvaluationError,
};

/// The Middlebury pairs of the shared test data (`stereo/NAME`) and the scale of their 8-bit
/// ground truth.
pub const MIDDLEBURY_PAIRS: [(&str, f32); 4] = [
    ("tsukuba", 16.0),
    ("venus", 8.0),
    ("cones", 4.0),
    ("teddy", 4.0),
];

/// The ground truth of a Middlebury pair directory: `disp_left.pgm` divided by `scale`, with
/// the pixels occluded according to `disp_right.pgm` (when there is one) masked.
pub fn load_middlebury_truth(dir: &Path, scale: f32) -> Result<DisparityMap, image::ImageError> {
    let mut truth =
        DisparityMap::from_scaled(&image::open(dir.join("disp_left.pgm"))?.to_luma8(), scale);
    let right = dir.join("disp_right.pgm");
    if right.exists() {
        let r = DisparityMap::from_scaled(&image::open(right)?.to_luma8(), scale);
        truth.mask_occlusions(&r, 1.0);
    }
    Ok(truth)
}

/// A rectified pair with its ground truth, as the accuracy tools read it.
#[derive(Debug, Clone)]
pub struct TruthPair {
    /// What it is (its directory's name).
    pub name: String,
    /// Left image (8-bit grey).
    pub left: image::GrayImage,
    /// Right image.
    pub right: image::GrayImage,
    /// The left view's ground truth, occlusions masked when the right one is given.
    pub truth: DisparityMap,
    /// Whether it is one of the shared pairs (parameters may be chosen on it) rather than an
    /// extra one.
    pub shared: bool,
}

/// Reads the pair in `dir`: `left` and `right` (`.ppm` or `.png`) and its truth
/// ([`load_middlebury_truth`] with `scale`).
pub fn load_truth_pair(
    dir: &Path,
    name: &str,
    scale: f32,
    shared: bool,
) -> Result<TruthPair, String> {
    let open = |stem: &str| -> Result<image::GrayImage, String> {
        for ext in ["ppm", "png"] {
            let p = dir.join(format!("{stem}.{ext}"));
            if p.exists() {
                return image::open(&p)
                    .map(|i| i.to_luma8())
                    .map_err(|e| format!("{}: {e}", p.display()));
            }
        }
        Err(format!("{}: no {stem}.ppm or {stem}.png", dir.display()))
    };
    Ok(TruthPair {
        name: name.to_string(),
        left: open("left")?,
        right: open("right")?,
        truth: load_middlebury_truth(dir, scale).map_err(|e| format!("{}: {e}", dir.display()))?,
        shared,
    })
}

/// The extra pairs under `dir` (`scripts/fetch-extra-stereo.sh`): every sub-directory holding
/// a `scale.txt` (the ground truth's scale), by name; none when `dir` does not exist.
pub fn load_extra_pairs(dir: &Path) -> Result<Vec<TruthPair>, String> {
    let mut dirs: Vec<std::path::PathBuf> = std::fs::read_dir(dir)
        .map(|d| d.filter_map(|e| e.ok().map(|e| e.path())).collect())
        .unwrap_or_default();
    dirs.sort();
    dirs.into_iter()
        .filter(|d| d.join("scale.txt").exists())
        .map(|d| {
            let path = d.join("scale.txt");
            let scale: f32 = std::fs::read_to_string(&path)
                .map_err(|e| format!("{}: {e}", path.display()))?
                .trim()
                .parse()
                .map_err(|e| format!("{}: {e}", path.display()))?;
            let name = d
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            load_truth_pair(&d, &name, scale, false)
        })
        .collect()
}

/// A dense disparity map; `NaN` marks unknown pixels.
#[derive(Debug, Clone)]
pub struct DisparityMap {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// Row-major disparities, pixels.
    pub values: Vec<f32>,
}

impl DisparityMap {
    /// From an 8-bit Middlebury map: disparity = value / `scale`, 0 = unknown.
    pub fn from_scaled(image: &image::GrayImage, scale: f32) -> Self {
        let values = image
            .as_raw()
            .iter()
            .map(|&v| if v == 0 { f32::NAN } else { v as f32 / scale })
            .collect();
        Self {
            width: image.width() as usize,
            height: image.height() as usize,
            values,
        }
    }

    /// Disparity at `(x, y)`, `None` outside the map or when unknown.
    pub fn at(&self, x: i64, y: i64) -> Option<f32> {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return None;
        }
        let v = self.values[y as usize * self.width + x as usize];
        (!v.is_nan()).then_some(v)
    }

    /// Marks as unknown the pixels failing the left-right check against `right` (the right
    /// view's map): occluded pixels and inconsistent ground truth.
    pub fn mask_occlusions(&mut self, right: &DisparityMap, tolerance_px: f32) {
        for y in 0..self.height {
            for x in 0..self.width {
                let i = y * self.width + x;
                let d = self.values[i];
                if d.is_nan() {
                    continue;
                }
                let xr = (x as f32 - d).round() as i64;
                let ok = right
                    .at(xr, y as i64)
                    .is_some_and(|dr| (dr - d).abs() <= tolerance_px);
                if !ok {
                    self.values[i] = f32::NAN;
                }
            }
        }
    }
}

/// Verdict on one match.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MatchVerdict {
    /// Median error <= 1 px.
    Correct,
    /// Median error > 1 px.
    Wrong,
    /// No usable ground truth along the segment.
    Unevaluated,
}

/// Judges the correspondence of a nearly horizontal match (see the module documentation).
pub fn judge_correspondence(left: &Segment, right: &Segment, truth: &DisparityMap) -> MatchVerdict {
    let steps = left.length_px.ceil().max(1.0) as usize;
    let (rx0, rx1) = if right.start[0] < right.end[0] {
        (right.start[0], right.end[0])
    } else {
        (right.end[0], right.start[0])
    };
    let (mut landing, mut could_land) = (0usize, 0usize);
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let x = left.start[0] + t * (left.end[0] - left.start[0]);
        let y = left.start[1] + t * (left.end[1] - left.start[1]);
        let (xi, yi) = (x.round() as i64, y.round() as i64);
        // Any known truth in the 5x5 window may apply (the edge may bound either surface).
        let mut lands = false;
        let mut in_extent = false;
        for dy in -2..=2 {
            for dx in -2..=2 {
                let Some(d) = truth.at(xi + dx, yi + dy) else {
                    continue;
                };
                let xr = x - d;
                if xr < rx0 - 1.0 || xr > rx1 + 1.0 {
                    continue;
                }
                in_extent = true;
                if point_segment_distance([xr, y], right) <= 1.5 {
                    lands = true;
                }
            }
        }
        if in_extent {
            could_land += 1;
            if lands {
                landing += 1;
            }
        }
    }
    if could_land == 0 {
        // No true correspondence of the left segment falls on the right segment's columns.
        return if truth_known_along(left, truth) {
            MatchVerdict::Wrong
        } else {
            MatchVerdict::Unevaluated
        };
    }
    if 2 * landing >= could_land {
        MatchVerdict::Correct
    } else {
        MatchVerdict::Wrong
    }
}

fn truth_known_along(s: &Segment, truth: &DisparityMap) -> bool {
    let steps = s.length_px.ceil().max(1.0) as usize;
    (0..=steps).any(|k| {
        let t = k as f32 / steps as f32;
        let x = s.start[0] + t * (s.end[0] - s.start[0]);
        let y = s.start[1] + t * (s.end[1] - s.start[1]);
        truth.at(x.round() as i64, y.round() as i64).is_some()
    })
}

/// Distance from point `p` to the segment `s` (its closest point, endpoints included), pixels.
pub fn point_segment_distance(p: [f32; 2], s: &Segment) -> f32 {
    let (dx, dy) = (s.end[0] - s.start[0], s.end[1] - s.start[1]);
    let len2 = (dx * dx + dy * dy).max(1e-9);
    let t = (((p[0] - s.start[0]) * dx + (p[1] - s.start[1]) * dy) / len2).clamp(0.0, 1.0);
    let (qx, qy) = (s.start[0] + t * dx, s.start[1] + t * dy);
    ((p[0] - qx).powi(2) + (p[1] - qy).powi(2)).sqrt()
}

/// Judges one match's disparity (see the module documentation).
pub fn judge_match(left: &Segment, m: &SegmentMatch, truth: &DisparityMap) -> MatchVerdict {
    let steps = left.length_px.ceil().max(1.0) as usize;
    let mut errors: Vec<f32> = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let x = left.start[0] + t * (left.end[0] - left.start[0]);
        let y = left.start[1] + t * (left.end[1] - left.start[1]);
        let d = m.disparity_px[0] + t * (m.disparity_px[1] - m.disparity_px[0]);
        let (xi, yi) = (x.round() as i64, y.round() as i64);
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let mut closest = f32::INFINITY;
        for dy in -2..=2 {
            for dx in -2..=2 {
                if let Some(v) = truth.at(xi + dx, yi + dy) {
                    lo = lo.min(v);
                    hi = hi.max(v);
                    closest = closest.min((v - d).abs());
                }
            }
        }
        if !closest.is_finite() {
            continue;
        }
        if hi - lo > 2.0 {
            errors.push(closest);
        } else if let Some(v) = truth.at(xi, yi) {
            errors.push((v - d).abs());
        }
    }
    if errors.is_empty() {
        return MatchVerdict::Unevaluated;
    }
    errors.sort_by(|a, b| a.total_cmp(b));
    if errors[errors.len() / 2] > 1.0 {
        MatchVerdict::Wrong
    } else {
        MatchVerdict::Correct
    }
}

/// Judges one match as [`evaluate`] does: nearly horizontal matches by their correspondence
/// ([`judge_correspondence`]), the others by their disparity ([`judge_match`]).
pub fn judge(
    left: &Segment,
    right: &Segment,
    m: &SegmentMatch,
    truth: &DisparityMap,
) -> MatchVerdict {
    if m.nearly_horizontal {
        judge_correspondence(left, right, truth)
    } else {
        judge_match(left, m, truth)
    }
}

/// Matching accuracy of one image pair.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct AccuracyReport {
    /// Segments extracted from the left image.
    pub left_segments: usize,
    /// Segments extracted from the right image.
    pub right_segments: usize,
    /// Accepted matches (= matched left segments).
    pub matches: usize,
    /// Matches of nearly horizontal segments among them.
    pub horizontal_matches: usize,
    /// Matches judged wrong (disparity for ordinary matches, correspondence for nearly
    /// horizontal ones).
    pub wrong: usize,
    /// Nearly horizontal matches whose endpoint disparity is off by more than 1 px (informative:
    /// that disparity is never used for 3D).
    pub horizontal_disparity_wrong: usize,
    /// Matches without usable ground truth.
    pub unevaluated: usize,
    /// Nearly horizontal matches judged wrong (by correspondence), among `wrong`.
    pub horizontal_wrong: usize,
    /// Nearly horizontal matches without usable ground truth, among `unevaluated`.
    pub horizontal_unevaluated: usize,
    /// Every match judged by its endpoint disparity alone (nearly horizontal ones included):
    /// wrong ones.
    pub disparity_wrong_all: usize,
    /// Every match judged by its endpoint disparity alone: unevaluated ones.
    pub disparity_unevaluated_all: usize,
}

impl AccuracyReport {
    /// Matched left segments / extracted left segments.
    pub fn matched_fraction(&self) -> f64 {
        self.matches as f64 / self.left_segments.max(1) as f64
    }

    /// Wrong matches / evaluated matches.
    pub fn wrong_fraction(&self) -> f64 {
        self.wrong as f64 / (self.matches - self.unevaluated).max(1) as f64
    }

    /// Wrong / evaluated when every match, nearly horizontal ones included, is judged by its
    /// endpoint disparity alone (the stricter reading; nearly horizontal matches' disparity is
    /// not observable along their rows and is never back-projected).
    pub fn disparity_wrong_fraction_all(&self) -> f64 {
        self.disparity_wrong_all as f64
            / (self.matches - self.disparity_unevaluated_all).max(1) as f64
    }

    /// Wrong / evaluated among the matches that are not nearly horizontal (the ones
    /// back-projected to 3D).
    pub fn wrong_fraction_not_horizontal(&self) -> f64 {
        let evaluated = self.matches
            - self.horizontal_matches
            - (self.unevaluated - self.horizontal_unevaluated);
        (self.wrong - self.horizontal_wrong) as f64 / evaluated.max(1) as f64
    }
}

/// Evaluates all matches of a run.
pub fn evaluate(
    left: &[Segment],
    right: &[Segment],
    matches: &[SegmentMatch],
    truth: &DisparityMap,
) -> AccuracyReport {
    let mut report = AccuracyReport {
        left_segments: left.len(),
        right_segments: right.len(),
        matches: matches.len(),
        ..AccuracyReport::default()
    };
    for m in matches {
        let l = &left[m.left as usize];
        let by_disparity = judge_match(l, m, truth);
        match by_disparity {
            MatchVerdict::Correct => {}
            MatchVerdict::Wrong => report.disparity_wrong_all += 1,
            MatchVerdict::Unevaluated => report.disparity_unevaluated_all += 1,
        }
        let verdict = if m.nearly_horizontal {
            report.horizontal_matches += 1;
            if by_disparity == MatchVerdict::Wrong {
                report.horizontal_disparity_wrong += 1;
            }
            let verdict = judge_correspondence(l, &right[m.right as usize], truth);
            match verdict {
                MatchVerdict::Correct => {}
                MatchVerdict::Wrong => report.horizontal_wrong += 1,
                MatchVerdict::Unevaluated => report.horizontal_unevaluated += 1,
            }
            verdict
        } else {
            by_disparity
        };
        match verdict {
            MatchVerdict::Correct => {}
            MatchVerdict::Wrong => report.wrong += 1,
            MatchVerdict::Unevaluated => report.unevaluated += 1,
        }
    }
    report
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertical segment at column `x`, rows 5..25, polarity +1 (shared by the evaluation's
    /// tests).
    pub(super) fn vertical(x: f32) -> Segment {
        Segment {
            start: [x, 5.0],
            end: [x, 25.0],
            length_px: 20.0,
            angle_rad: std::f32::consts::FRAC_PI_2,
            polarity: 1,
            contrast: 50.0,
            side_intensity: [0.0, 0.0],
            chain: 0,
        }
    }

    fn m(d: f32) -> SegmentMatch {
        SegmentMatch {
            left: 0,
            right: 0,
            disparity_px: [d, d],
            support: 1,
            predicted: true,
            nearly_horizontal: false,
            evidence: Default::default(),
        }
    }

    #[test]
    fn correct_wrong_and_unknown_are_told_apart() {
        // Two surfaces: d = 10 left of x = 20, d = 20 from x = 20 on.
        let (w, h) = (40, 30);
        let mut values = vec![0.0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                values[y * w + x] = if x < 20 { 10.0 } else { 20.0 };
            }
        }
        let truth = DisparityMap {
            width: w,
            height: h,
            values,
        };
        assert_eq!(
            judge_match(&vertical(8.0), &m(10.5), &truth),
            MatchVerdict::Correct
        );
        assert_eq!(
            judge_match(&vertical(8.0), &m(12.0), &truth),
            MatchVerdict::Wrong
        );
        // On the discontinuity either surface is accepted, nothing in between.
        assert_eq!(
            judge_match(&vertical(19.0), &m(20.0), &truth),
            MatchVerdict::Correct
        );
        assert_eq!(
            judge_match(&vertical(19.0), &m(10.0), &truth),
            MatchVerdict::Correct
        );
        assert_eq!(
            judge_match(&vertical(19.0), &m(15.0), &truth),
            MatchVerdict::Wrong
        );
        let unknown = DisparityMap {
            width: w,
            height: h,
            values: vec![f32::NAN; w * h],
        };
        assert_eq!(
            judge_match(&vertical(8.0), &m(10.0), &unknown),
            MatchVerdict::Unevaluated
        );
    }

    #[test]
    fn occlusion_mask_drops_inconsistent_pixels() {
        let mut left = DisparityMap {
            width: 10,
            height: 1,
            values: vec![2.0; 10],
        };
        let mut right_values = vec![2.0; 10];
        right_values[3] = 5.0; // left x = 5 maps to right x = 3, which disagrees
        let right = DisparityMap {
            width: 10,
            height: 1,
            values: right_values,
        };
        left.mask_occlusions(&right, 1.0);
        assert!(left.values[5].is_nan());
        assert!(left.values[0].is_nan(), "maps outside the right image");
        assert_eq!(left.values[6], 2.0);
    }
}
