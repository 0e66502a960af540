//! Phantom relief: where a built bas-relief departs from the true surface, by area on the
//! device.
//!
//! A wrong stereo match back-projects to a 3D segment that is not in the scene, and the surface
//! builder turns it into a ridge or a hole the wearer feels; interpolation between correct
//! segments across parts of the scene where no segment was matched departs from the scene too.
//! Both are measured here against a ground-truth disparity map of the left image, in the
//! device's own units (metres of relief, square metres of explorable area), so that a threshold
//! means what the finger feels.
//!
//! What is measured, pixel by pixel ([`relief_deviation`]): for every left-image pixel
//! `(x, y)` (pixel centres at integer coordinates, as the segments' endpoints) whose true
//! disparity `d` is known and positive,
//!
//! 1. the true scene point is back-projected with the rectified geometry
//!    (`Z = f B / d`, [`RectifiedGeometry::back_project`]) and seen through the left camera's
//!    pinhole (focal length and principal point of the geometry, as the relief was built);
//! 2. it is mapped into the device frame with the relief's own [`ReliefParams::scene_map`]: its
//!    image position gives the device `(x, y)` on the explorable area, its depth `Z` the true
//!    relief height `z_true` (the depth is clamped to the mapped depth range exactly as the
//!    relief's own vertices are);
//! 3. the pixel is skipped when that device point lies outside the explorable area or inside
//!    its frame (the band of `max(frame_width_m, merge_distance_m)` along the border that the
//!    builder holds at the back plane whatever the scene: not a property of the matches);
//! 4. otherwise the relief's height `z_relief` under that device `(x, y)` is read
//!    ([`ReliefModel::height_at`]) and the pixel's **deviation** is `z_relief - z_true`, along
//!    the device's `z` axis (the reference normal the relief is pressed along; positive: the
//!    relief lies behind the true surface, a hole; negative: in front of it, a ridge). It is a
//!    vertical difference at the same device `(x, y)`, not a distance to the nearest point of
//!    the surface: where the relief ramps across a depth discontinuity the whole ramp deviates.
//!
//! Every evaluated pixel stands for its device footprint, the area one image pixel covers on
//! the explorable area (the scene map is linear, so all pixels have the same footprint). A
//! pixel **deviates** at a threshold `t` when `|deviation| > t`; [`ReliefDeviation::phantom`]
//! sums the footprints of the evaluated and of the deviating pixels and finds the largest
//! 4-connected region of deviating pixels ([`PhantomArea`]).
//!
//! Part of that deviation is there whatever the matches: the relief interpolates between
//! correct segments across depth steps and ramps down to the back plane at the area's border.
//! [`ReliefDeviation::excess_over`] separates what wrong matches add: given the deviation of a
//! **floor** relief (built with the same scene map from only the correct matches), a pixel is
//! in the **excess** when it deviates in this relief but not in the floor; the excess's area
//! and its largest 4-connected region are the phantom relief the wrong matches make the wearer
//! feel.

use videt_relief::{PinholeCamera, ReliefModel, ReliefParams};
use videt_vision::reconstruct::RectifiedGeometry;

use super::DisparityMap;

/// Why a relief could not be compared with the ground truth.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReliefEvaluationError {
    /// The ground truth is not the size of the image the relief's scene map stretches over the
    /// area.
    #[error(
        "ground truth is {truth_width}x{truth_height} pixels but the relief maps a \
         {image_width}x{image_height} image"
    )]
    SizeMismatch {
        /// Ground truth width, pixels.
        truth_width: usize,
        /// Ground truth height, pixels.
        truth_height: usize,
        /// Image width of the scene map, pixels.
        image_width: f64,
        /// Image height of the scene map, pixels.
        image_height: f64,
    },
    /// Two deviations compared pixel by pixel are not of the same image or footprint.
    #[error(
        "deviation of a {width}x{height} image ({pixel_area_m2} m^2 per pixel) compared with \
         one of a {floor_width}x{floor_height} image ({floor_pixel_area_m2} m^2 per pixel)"
    )]
    FloorMismatch {
        /// Width of the compared deviation, pixels.
        width: usize,
        /// Its height, pixels.
        height: usize,
        /// Its pixel footprint, square metres.
        pixel_area_m2: f64,
        /// Width of the floor's deviation, pixels.
        floor_width: usize,
        /// Its height, pixels.
        floor_height: usize,
        /// Its pixel footprint, square metres.
        floor_pixel_area_m2: f64,
    },
    /// The rectified geometry's focal length or baseline is not positive and finite.
    #[error("rectified geometry: focal length {focal_px} px and baseline {baseline_m} m must be finite and > 0")]
    Geometry {
        /// Focal length, pixels.
        focal_px: f64,
        /// Baseline, metres.
        baseline_m: f64,
    },
}

/// The relief's deviation from the true surface at every left-image pixel (see the module
/// documentation for what is measured).
#[derive(Debug, Clone, PartialEq)]
pub struct ReliefDeviation {
    /// Width of the left image, pixels.
    pub width: usize,
    /// Height of the left image, pixels.
    pub height: usize,
    /// Device area one pixel covers on the explorable area, square metres.
    pub pixel_area_m2: f64,
    /// Row-major `z_relief - z_true` per pixel, metres (device `z`; positive: the relief lies
    /// behind the true surface); `NaN` where the pixel is not evaluated (unknown truth, or
    /// outside the area or inside its frame).
    pub deviation_m: Vec<f64>,
}

/// The phantom relief at one threshold: how much of the evaluated area departs from the true
/// surface by more than the threshold.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhantomArea {
    /// The threshold on `|z_relief - z_true|`, metres.
    pub threshold_m: f64,
    /// Pixels evaluated (known truth, inside the area and its frame).
    pub evaluated_pixels: usize,
    /// Their device area, square metres.
    pub evaluated_area_m2: f64,
    /// Evaluated pixels deviating by more than the threshold.
    pub deviating_pixels: usize,
    /// Their device area (the phantom area), square metres.
    pub deviating_area_m2: f64,
    /// Pixels of the largest 4-connected region of deviating pixels.
    pub largest_region_pixels: usize,
    /// Its device area, square metres.
    pub largest_region_m2: f64,
}

impl PhantomArea {
    /// Deviating area / evaluated area (0 when nothing was evaluated).
    pub fn deviating_fraction(&self) -> f64 {
        if self.evaluated_pixels == 0 {
            0.0
        } else {
            self.deviating_pixels as f64 / self.evaluated_pixels as f64
        }
    }
}

impl ReliefDeviation {
    /// The deviation at pixel `(x, y)`, metres; `None` outside the image or where the pixel is
    /// not evaluated.
    pub fn at(&self, x: usize, y: usize) -> Option<f64> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let v = self.deviation_m[y * self.width + x];
        (!v.is_nan()).then_some(v)
    }

    /// Whether each pixel (row-major) is evaluated and deviates by more than `threshold_m`.
    pub fn deviating_mask(&self, threshold_m: f64) -> Vec<bool> {
        self.deviation_m
            .iter()
            .map(|v| v.abs() > threshold_m)
            .collect()
    }

    /// Evaluated and deviating areas at `threshold_m` (metres, compared with
    /// `|z_relief - z_true|`), and the largest 4-connected deviating region.
    pub fn phantom(&self, threshold_m: f64) -> PhantomArea {
        let evaluated_pixels = self.deviation_m.iter().filter(|v| !v.is_nan()).count();
        self.area_of(
            threshold_m,
            evaluated_pixels,
            self.deviating_mask(threshold_m),
        )
    }

    /// Whether each pixel (row-major) is in the excess over `floor` at `threshold_m`: evaluated
    /// in both, deviating by more than the threshold here and not in `floor`. `floor` must be
    /// the deviation of a relief of the same image and footprint (see
    /// [`ReliefDeviation::excess_over`]).
    pub fn excess_mask(
        &self,
        floor: &ReliefDeviation,
        threshold_m: f64,
    ) -> Result<Vec<bool>, ReliefEvaluationError> {
        self.check_floor(floor)?;
        Ok(self
            .deviation_m
            .iter()
            .zip(&floor.deviation_m)
            .map(|(v, f)| !f.is_nan() && v.abs() > threshold_m && f.abs() <= threshold_m)
            .collect())
    }

    /// The phantom area proper: the deviation this relief adds to `floor`'s, pixel by pixel.
    ///
    /// `floor` is the deviation of the relief built, with the same scene map (so that both
    /// share the image, the footprint and the pixels evaluated), from only the correct
    /// matches. A pixel counts when it is evaluated in both, deviates by more than
    /// `threshold_m` here and does not in `floor`; a pixel deviating in both counts for
    /// neither (its deviation is there without the wrong matches). In the returned
    /// [`PhantomArea`], `evaluated_*` are the pixels evaluated in both, `deviating_*` the
    /// excess and `largest_region_*` the largest 4-connected region of the excess.
    ///
    /// The excess is what the other matches add only when this relief keeps every segment of
    /// the floor's; where it lacks some, the interpolation across their place counts too.
    pub fn excess_over(
        &self,
        floor: &ReliefDeviation,
        threshold_m: f64,
    ) -> Result<PhantomArea, ReliefEvaluationError> {
        let mask = self.excess_mask(floor, threshold_m)?;
        let evaluated_pixels = self
            .deviation_m
            .iter()
            .zip(&floor.deviation_m)
            .filter(|(v, f)| !v.is_nan() && !f.is_nan())
            .count();
        Ok(self.area_of(threshold_m, evaluated_pixels, mask))
    }

    fn check_floor(&self, floor: &ReliefDeviation) -> Result<(), ReliefEvaluationError> {
        let same_footprint = (self.pixel_area_m2 - floor.pixel_area_m2).abs()
            <= 1e-9 * self.pixel_area_m2.abs().max(floor.pixel_area_m2.abs());
        if self.width == floor.width && self.height == floor.height && same_footprint {
            Ok(())
        } else {
            Err(ReliefEvaluationError::FloorMismatch {
                width: self.width,
                height: self.height,
                pixel_area_m2: self.pixel_area_m2,
                floor_width: floor.width,
                floor_height: floor.height,
                floor_pixel_area_m2: floor.pixel_area_m2,
            })
        }
    }

    /// The areas of `mask` (counted as deviating) among `evaluated_pixels`.
    fn area_of(
        &self,
        threshold_m: f64,
        evaluated_pixels: usize,
        mut mask: Vec<bool>,
    ) -> PhantomArea {
        let deviating_pixels = mask.iter().filter(|&&m| m).count();
        let largest_region_pixels = largest_region(&mut mask, self.width, self.height);
        PhantomArea {
            threshold_m,
            evaluated_pixels,
            evaluated_area_m2: evaluated_pixels as f64 * self.pixel_area_m2,
            deviating_pixels,
            deviating_area_m2: deviating_pixels as f64 * self.pixel_area_m2,
            largest_region_pixels,
            largest_region_m2: largest_region_pixels as f64 * self.pixel_area_m2,
        }
    }
}

/// Pixels of the largest 4-connected region of `mask` (cleared on the way).
fn largest_region(mask: &mut [bool], width: usize, height: usize) -> usize {
    let mut largest = 0;
    let mut stack: Vec<usize> = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] {
            continue;
        }
        mask[start] = false;
        stack.push(start);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % width, i / width);
            let mut visit = |j: usize| {
                if mask[j] {
                    mask[j] = false;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < width {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - width);
            }
            if y + 1 < height {
                visit(i + width);
            }
        }
        largest = largest.max(size);
    }
    largest
}

/// The deviation of `model` from the true surface at every pixel of `truth` (the left image's
/// ground-truth disparity, `NaN` unknown): see the module documentation. `params` must be the
/// settings the relief was built with and `geometry` the rectified geometry its segments were
/// back-projected with and projected through (the left pinhole of focal length
/// `geometry.focal_px` and principal point `(cx_px, cy_px)`).
pub fn relief_deviation(
    model: &ReliefModel,
    params: &ReliefParams,
    geometry: &RectifiedGeometry,
    truth: &DisparityMap,
) -> Result<ReliefDeviation, ReliefEvaluationError> {
    let map = &params.scene_map;
    let [image_width, image_height] = map.image_size_px();
    if truth.width as f64 != image_width || truth.height as f64 != image_height {
        return Err(ReliefEvaluationError::SizeMismatch {
            truth_width: truth.width,
            truth_height: truth.height,
            image_width,
            image_height,
        });
    }
    if geometry.validate().is_err() {
        return Err(ReliefEvaluationError::Geometry {
            focal_px: geometry.focal_px,
            baseline_m: geometry.baseline_m,
        });
    }
    let camera = PinholeCamera {
        focal_px: geometry.focal_px,
        cx_px: geometry.cx_px,
        cy_px: geometry.cy_px,
    };
    // The area inside the frame the builder holds at the back plane.
    let area = params.area_m();
    let frame = params.frame_width_m.max(params.merge_distance_m);
    let inner = [
        area[0] + frame,
        area[1] + frame,
        area[2] - frame,
        area[3] - frame,
    ];
    let origin = map.image_to_workspace(0.0, 0.0);
    let unit = map.image_to_workspace(1.0, 1.0);
    let pixel_area_m2 = ((unit[0] - origin[0]) * (unit[1] - origin[1])).abs();
    let mut deviation_m = vec![f64::NAN; truth.width * truth.height];
    for y in 0..truth.height {
        for x in 0..truth.width {
            let d = truth.values[y * truth.width + x];
            if !(d.is_finite() && d > 0.0) {
                continue;
            }
            let Some((point, _)) = geometry.back_project(x as f64, y as f64, f64::from(d), 0.0)
            else {
                continue;
            };
            let Some(([u, v], depth_m)) = camera.project(&[point.x, point.y, point.z]) else {
                continue;
            };
            let [dx, dy] = map.image_to_workspace(u, v);
            if !(dx >= inner[0] && dx <= inner[2] && dy >= inner[1] && dy <= inner[3]) {
                continue;
            }
            let Some(sample) = model.height_at(dx, dy) else {
                continue;
            };
            deviation_m[y * truth.width + x] = sample.z_m - map.scene_depth_to_relief_z(depth_m);
        }
    }
    Ok(ReliefDeviation {
        width: truth.width,
        height: truth.height,
        pixel_area_m2,
        deviation_m,
    })
}

/// The phantom relief of `model` at `threshold_m`: [`relief_deviation`] then
/// [`ReliefDeviation::phantom`].
pub fn phantom_area(
    model: &ReliefModel,
    params: &ReliefParams,
    geometry: &RectifiedGeometry,
    truth: &DisparityMap,
    threshold_m: f64,
) -> Result<PhantomArea, ReliefEvaluationError> {
    Ok(relief_deviation(model, params, geometry, truth)?.phantom(threshold_m))
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_control::SceneMap;
    use videt_relief::{build_from_scene, SceneSegment3};

    const W: usize = 200;
    const H: usize = 150;
    /// Background and box depths, metres.
    const Z_BACKGROUND: f64 = 3.0;
    const Z_BOX: f64 = 2.0;
    /// Columns of unknown truth.
    const UNKNOWN_COLUMNS: std::ops::RangeInclusive<usize> = 150..=160;
    /// The box's pixels (inclusive).
    const BOX: [usize; 4] = [80, 50, 120, 100];

    fn geometry() -> RectifiedGeometry {
        RectifiedGeometry {
            focal_px: 200.0,
            cx_px: (W as f64 - 1.0) / 2.0,
            cy_px: (H as f64 - 1.0) / 2.0,
            baseline_m: 0.1,
        }
    }

    /// The image stretched over 40 x 30 cm (2 mm per pixel), 8 cm of relief in front of a back
    /// plane at 45 cm, scene depths 2..4 m.
    fn params() -> ReliefParams {
        let map = SceneMap::new(
            [0.0, 0.0],
            [0.4, 0.3],
            [W as u32, H as u32],
            0.45,
            0.08,
            [2.0, 4.0],
        )
        .unwrap();
        ReliefParams::new(map)
    }

    fn disparity(z: f64) -> f64 {
        geometry().focal_px * geometry().baseline_m / z
    }

    fn in_box(x: usize, y: usize) -> bool {
        (BOX[0]..=BOX[2]).contains(&x) && (BOX[1]..=BOX[3]).contains(&y)
    }

    /// The truth of the box scene: a fronto-parallel box face at 2 m over a background at 3 m,
    /// a band of unknown columns.
    fn truth() -> DisparityMap {
        let mut values = vec![0.0f32; W * H];
        for y in 0..H {
            for x in 0..W {
                values[y * W + x] = if UNKNOWN_COLUMNS.contains(&x) {
                    f32::NAN
                } else if in_box(x, y) {
                    disparity(Z_BOX) as f32
                } else {
                    disparity(Z_BACKGROUND) as f32
                };
            }
        }
        DisparityMap {
            width: W,
            height: H,
            values,
        }
    }

    /// The camera-frame segment between pixels `a` and `b` at depth `z`.
    fn segment(a: [f64; 2], b: [f64; 2], z: f64) -> SceneSegment3 {
        let g = geometry();
        let p = |q: [f64; 2]| {
            let (v, _) = g.back_project(q[0], q[1], disparity(z), 0.0).unwrap();
            [v.x, v.y, v.z]
        };
        SceneSegment3 {
            a_m: p(a),
            b_m: p(b),
        }
    }

    fn rectangle(r: [f64; 4], z: f64) -> Vec<SceneSegment3> {
        let [x0, y0, x1, y1] = r;
        vec![
            segment([x0, y0], [x1, y0], z),
            segment([x1, y0], [x1, y1], z),
            segment([x1, y1], [x0, y1], z),
            segment([x0, y1], [x0, y0], z),
        ]
    }

    /// Exact segments of the box scene: the box's outline, a ring one pixel outside it on the
    /// background, the background's border just inside the frame, and short background
    /// segments on a lattice (every 8 px) away from the box.
    fn exact_segments() -> Vec<SceneSegment3> {
        let b = BOX.map(|v| v as f64);
        let mut s = rectangle(b, Z_BOX);
        s.extend(rectangle(
            [b[0] - 1.0, b[1] - 1.0, b[2] + 1.0, b[3] + 1.0],
            Z_BACKGROUND,
        ));
        s.extend(rectangle([3.0, 3.0, 197.0, 147.0], Z_BACKGROUND));
        for x in (6..=194).step_by(8) {
            for y in (6..=138).step_by(8) {
                if (70..=130).contains(&x) && (40..=110).contains(&y) {
                    continue;
                }
                let (x, y) = (x as f64, y as f64);
                s.push(segment([x, y], [x, y + 6.0], Z_BACKGROUND));
            }
        }
        s
    }

    fn build(segments: &[SceneSegment3]) -> ReliefModel {
        let g = geometry();
        let camera = PinholeCamera {
            focal_px: g.focal_px,
            cx_px: g.cx_px,
            cy_px: g.cy_px,
        };
        let (model, report) = build_from_scene(segments, &[], &camera, &params()).unwrap();
        assert!(report.rejections.is_empty(), "{:?}", report.rejections);
        model
    }

    #[test]
    fn exact_segments_give_no_phantom_area_and_skip_unknown_and_frame_pixels() {
        let deviation =
            relief_deviation(&build(&exact_segments()), &params(), &geometry(), &truth()).unwrap();
        let worst = deviation
            .deviation_m
            .iter()
            .filter(|v| !v.is_nan())
            .fold(0.0f64, |w, v| w.max(v.abs()));
        // The truth is stored as f32: depths agree to about 1e-7 relative.
        assert!(worst < 1e-6, "worst deviation {worst} m");
        let phantom = deviation.phantom(0.005);
        // 2 mm pixels; the 5 mm frame leaves columns 3..=197 and rows 3..=147.
        assert!((deviation.pixel_area_m2 - 4e-6).abs() < 1e-15);
        let evaluated = (195 - UNKNOWN_COLUMNS.count()) * 145;
        assert_eq!(phantom.evaluated_pixels, evaluated);
        assert!((phantom.evaluated_area_m2 - evaluated as f64 * 4e-6).abs() < 1e-12);
        assert_eq!(phantom.deviating_pixels, 0);
        assert_eq!(phantom.largest_region_m2, 0.0);
        assert_eq!(phantom.deviating_fraction(), 0.0);
        assert_eq!(deviation.at(155, 75), None, "unknown truth");
        assert_eq!(deviation.at(1, 75), None, "in the frame");
        assert!(deviation.at(100, 75).is_some());
    }

    #[test]
    fn a_wrong_segment_makes_phantom_area_that_grows_with_it() {
        let mut previous = 0.0;
        for length in [8.0, 16.0, 32.0, 64.0] {
            let mut segments = exact_segments();
            // A match 1 m too near on the background, between two lattice columns.
            segments.push(segment([50.0, 20.0], [50.0, 20.0 + length], Z_BOX));
            let model = build(&segments);
            let phantom = phantom_area(&model, &params(), &geometry(), &truth(), 0.005).unwrap();
            assert!(
                phantom.deviating_area_m2 > previous,
                "{length} px: {phantom:?} after {previous} m^2"
            );
            // One wrong segment: one region, a ridge standing 4 cm out at the segment.
            assert_eq!(phantom.largest_region_pixels, phantom.deviating_pixels);
            let deviation = relief_deviation(&model, &params(), &geometry(), &truth()).unwrap();
            let middle = (20.0 + length / 2.0) as usize;
            assert!((deviation.at(50, middle).unwrap() + 0.04).abs() < 1e-6);
            // Its area: about the segment's length times the lattice's 16 px between
            // neighbouring background columns.
            let pixels = phantom.deviating_pixels as f64;
            assert!(pixels < (length + 16.0) * 16.0, "{length} px: {pixels}");
            previous = phantom.deviating_area_m2;
        }
    }

    #[test]
    fn phantom_area_never_grows_with_the_threshold() {
        let mut segments = exact_segments();
        segments.push(segment([50.0, 20.0], [50.0, 60.0], Z_BOX));
        segments.push(segment([170.0, 90.0], [170.0, 120.0], 4.0));
        let deviation =
            relief_deviation(&build(&segments), &params(), &geometry(), &truth()).unwrap();
        let mut previous = deviation.phantom(0.0);
        assert!(previous.deviating_pixels > 0);
        for k in 1..=100 {
            let p = deviation.phantom(k as f64 * 0.0005);
            assert_eq!(p.evaluated_pixels, previous.evaluated_pixels);
            assert!(p.deviating_pixels <= previous.deviating_pixels, "{p:?}");
            assert!(p.largest_region_pixels <= previous.largest_region_pixels);
            assert!(p.largest_region_pixels <= p.deviating_pixels);
            previous = p;
        }
        // Nothing deviates by more than the whole relief depth.
        assert_eq!(deviation.phantom(0.08).deviating_pixels, 0);
        assert!(
            deviation.phantom(0.005).largest_region_pixels
                < deviation.phantom(0.005).deviating_pixels
        );
    }

    /// The deviation of the relief built from `segments`.
    fn deviation_of(segments: &[SceneSegment3]) -> ReliefDeviation {
        relief_deviation(&build(segments), &params(), &geometry(), &truth()).unwrap()
    }

    /// A match 1 m too near on the background, between two lattice columns, 40 px long.
    fn wrong_segment() -> SceneSegment3 {
        segment([50.0, 20.0], [50.0, 60.0], Z_BOX)
    }

    /// The exact segments without the box's outline and the ring around it: the relief
    /// interpolates the background across the box, which deviates there.
    fn segments_without_box() -> Vec<SceneSegment3> {
        exact_segments().split_off(8)
    }

    #[test]
    fn identical_reliefs_have_no_excess() {
        let mut with_wrong = segments_without_box();
        with_wrong.push(wrong_segment());
        for segments in [exact_segments(), segments_without_box(), with_wrong] {
            let deviation = deviation_of(&segments);
            let excess = deviation.excess_over(&deviation, 0.005).unwrap();
            assert_eq!(excess.deviating_pixels, 0);
            assert_eq!(excess.deviating_area_m2, 0.0);
            assert_eq!(excess.largest_region_pixels, 0);
            assert_eq!(
                excess.evaluated_pixels,
                deviation.phantom(0.005).evaluated_pixels
            );
        }
    }

    #[test]
    fn an_injected_wrong_segment_adds_the_area_of_its_bump() {
        // Over the exact relief: the excess is the whole bump, one region around the segment.
        let floor = deviation_of(&exact_segments());
        let mut segments = exact_segments();
        segments.push(wrong_segment());
        let with = deviation_of(&segments);
        let bump = with.phantom(0.005);
        assert!(bump.deviating_pixels > 0);
        let excess = with.excess_over(&floor, 0.005).unwrap();
        assert_eq!(excess, bump);
        assert_eq!(excess.largest_region_pixels, excess.deviating_pixels);
        let mask = with.excess_mask(&floor, 0.005).unwrap();
        assert!(mask[40 * W + 50], "at the segment");
        assert!(!mask[40 * W + 140] && !mask[75 * W + 100], "away from it");

        // Over a floor that deviates elsewhere (the box is missing): the same bump, whatever
        // the floor's own deviation.
        let floor = deviation_of(&segments_without_box());
        assert!(floor.phantom(0.005).deviating_pixels > 1000);
        let mut segments = segments_without_box();
        segments.push(wrong_segment());
        let with = deviation_of(&segments);
        let excess = with.excess_over(&floor, 0.005).unwrap();
        assert_eq!(excess.deviating_pixels, bump.deviating_pixels);
        assert_eq!(excess.largest_region_pixels, bump.deviating_pixels);
        assert!((excess.deviating_area_m2 - bump.deviating_area_m2).abs() < 1e-15);
        assert_eq!(
            with.phantom(0.005).deviating_pixels,
            floor.phantom(0.005).deviating_pixels + bump.deviating_pixels
        );
    }

    #[test]
    fn a_pixel_deviating_in_both_counts_for_neither() {
        // Pixels: deviating in both, only here, only in the floor, in neither, unevaluated in
        // the floor, unevaluated here.
        let nan = f64::NAN;
        let deviation = |values: Vec<f64>| ReliefDeviation {
            width: 6,
            height: 1,
            pixel_area_m2: 1e-6,
            deviation_m: values,
        };
        let with = deviation(vec![0.02, -0.01, 0.0, 0.001, 0.03, nan]);
        let floor = deviation(vec![-0.03, 0.002, 0.01, 0.0, nan, 0.02]);
        assert_eq!(
            with.excess_mask(&floor, 0.005).unwrap(),
            vec![false, true, false, false, false, false]
        );
        let excess = with.excess_over(&floor, 0.005).unwrap();
        assert_eq!(excess.evaluated_pixels, 4);
        assert_eq!(excess.deviating_pixels, 1);
        assert!((excess.deviating_area_m2 - 1e-6).abs() < 1e-18);
        assert_eq!(excess.largest_region_pixels, 1);

        // A wrong segment inside the floor's own deviation adds nothing there.
        let floor = deviation_of(&segments_without_box());
        let mut segments = segments_without_box();
        segments.push(segment([95.0, 65.0], [95.0, 85.0], Z_BACKGROUND));
        let with = deviation_of(&segments);
        let floor_mask = floor.deviating_mask(0.005);
        let mask = with.excess_mask(&floor, 0.005).unwrap();
        assert!(mask.iter().zip(&floor_mask).all(|(e, f)| !(*e && *f)));
        assert!(with.deviating_mask(0.005)[75 * W + 95] && floor_mask[75 * W + 95]);
        assert!(!mask[75 * W + 95]);

        // Deviations of another image are refused.
        let other = deviation(vec![0.0; 6]);
        assert!(matches!(
            with.excess_over(&other, 0.005),
            Err(ReliefEvaluationError::FloorMismatch { .. })
        ));
    }

    #[test]
    fn mismatched_truth_or_geometry_is_refused() {
        let model = build(&exact_segments());
        let small = DisparityMap {
            width: 10,
            height: 10,
            values: vec![1.0; 100],
        };
        let e = relief_deviation(&model, &params(), &geometry(), &small).unwrap_err();
        assert!(e.to_string().contains("10x10"), "{e}");
        let mut g = geometry();
        g.baseline_m = 0.0;
        assert!(matches!(
            relief_deviation(&model, &params(), &g, &truth()),
            Err(ReliefEvaluationError::Geometry { .. })
        ));
    }
}
