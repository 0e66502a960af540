//! What the surface is built from, and the settings of the build.
//!
//! The input is independent of the stereo code: 3D segments and points in the left camera's
//! frame (`x` right, `y` down, `z` forward, metres), which a pinhole projects into the left image
//! and the [`SceneMap`] maps into the device workspace; or segments already in device
//! coordinates (`x`, `y` on the explorable area, `z` the relief height).

use videt_control::SceneMap;

/// A 3D line segment in the left camera's frame, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneSegment3 {
    /// One endpoint `(X, Y, Z)`, metres (`Z` > 0: in front of the camera).
    pub a_m: [f64; 3],
    /// The other endpoint, metres.
    pub b_m: [f64; 3],
}

/// A segment already in device coordinates: `(x, y)` on the explorable area and `z` the relief
/// height, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceSegment {
    /// One endpoint, metres.
    pub a_m: [f64; 3],
    /// The other endpoint, metres.
    pub b_m: [f64; 3],
}

/// The left camera's pinhole (rectified): pixel `u = f X / Z + cx`, `v = f Y / Z + cy`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PinholeCamera {
    /// Focal length, pixels (> 0).
    pub focal_px: f64,
    /// Principal point column, pixels.
    pub cx_px: f64,
    /// Principal point row, pixels.
    pub cy_px: f64,
}

impl PinholeCamera {
    /// The image pixel `(u, v)` and the depth `Z` of a camera-frame point; `None` when the point
    /// is not finite or not in front of the camera.
    pub fn project(&self, p_m: &[f64; 3]) -> Option<([f64; 2], f64)> {
        let [x, y, z] = *p_m;
        if !(x.is_finite() && y.is_finite() && z.is_finite() && z > 1e-9) {
            return None;
        }
        let u = self.focal_px * x / z + self.cx_px;
        let v = self.focal_px * y / z + self.cy_px;
        (u.is_finite() && v.is_finite()).then_some(([u, v], z))
    }
}

/// Settings of the surface build.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReliefParams {
    /// Workspace ↔ image and scene depth ↔ relief mapping.
    pub scene_map: SceneMap,
    /// Points closer than this on the area are merged (the nearest one's height wins), metres
    /// (> 0).
    pub merge_distance_m: f64,
    /// Width of the frame around the explorable area kept at the back plane, metres (>= 0, less
    /// than a quarter of the area's smaller side). Scene geometry inside it is clipped off.
    pub frame_width_m: f64,
    /// Spacing of the frame's vertices along the area's border, metres (> 0).
    pub border_spacing_m: f64,
    /// Two segments whose images cross are split at the crossing when their relief heights there
    /// differ by at most this; otherwise the farther one is occluded and is not kept as a
    /// constraint, metres (>= 0).
    pub crossing_tolerance_m: f64,
    /// Acceleration grid: cells per triangle (> 0; about 1-2 gives one or two triangles per
    /// cell).
    pub grid_cells_per_triangle: f64,
    /// How the surface spans the gaps between the segments: the paper's interpolation, or depth
    /// steps kept as steps and the border at the height of what is near it.
    pub shape: ReliefShape,
    /// [`ReliefShape::Stepped`]: an edge of the triangulation between two segments is a depth
    /// step when its ends' heights differ by more than this, metres (> 0)...
    pub step_min_height_m: f64,
    /// ... and a triangle on it is steeper than this (the gradient of its height on the area;
    /// > 0, 1 is 45 degrees).
    pub step_min_slope: f64,
    /// [`ReliefShape::Stepped`]: width of a step's wall on the area, metres (> 0, less than the
    /// frame's width when there is a frame): the surface drops from the nearer end's height to
    /// the farther end's within this distance of the nearer end.
    pub step_width_m: f64,
    /// [`ReliefShape::Stepped`]: the steepest a step's wall may be (rise over width on the
    /// area, > 0): a higher step gets a wider wall, so that the rendering's proxy holds the
    /// finger on it.
    pub step_max_wall_slope: f64,
}

/// How the relief spans the gaps between the 3-D segments.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReliefShape {
    /// The paper's surface: the constrained Delaunay triangulation interpolates the height
    /// linearly everywhere, across depth steps too, and the area's border is at the back plane.
    Interpolated,
    /// Depth steps kept as steps: where a triangle spans a step (see
    /// [`ReliefParams::step_min_height_m`]), the surface holds the farther height up to a wall
    /// [`ReliefParams::step_width_m`] wide at the nearer side, as at an occluding edge; the
    /// frame's inner border takes the height of the nearest segment or point, so the area does
    /// not ramp down to the back plane (the frame itself does).
    Stepped,
}

impl ReliefParams {
    /// Defaults for a scene map: 0.3 mm merging, a 5 mm frame with a vertex every 2 cm, 2 mm
    /// crossing tolerance, one grid cell per triangle; the paper's interpolated surface
    /// ([`ReliefShape::Interpolated`]). For [`ReliefShape::Stepped`], the step settings: heights
    /// differing by more than 3 mm across a triangle steeper than 0.5 (27 degrees), walls 3 mm
    /// wide or wider, at most 4 high for 1 wide (76 degrees).
    pub fn new(scene_map: SceneMap) -> ReliefParams {
        ReliefParams {
            scene_map,
            merge_distance_m: 3e-4,
            frame_width_m: 0.005,
            border_spacing_m: 0.02,
            crossing_tolerance_m: 0.002,
            grid_cells_per_triangle: 1.0,
            shape: ReliefShape::Interpolated,
            step_min_height_m: 0.003,
            step_min_slope: 0.5,
            step_width_m: 0.003,
            step_max_wall_slope: 4.0,
        }
    }

    /// The explorable area `[x_min, y_min, x_max, y_max]`, metres.
    pub fn area_m(&self) -> [f64; 4] {
        let [w, h] = self.scene_map.image_size_px();
        let [x0, y0] = self.scene_map.image_to_workspace(0.0, h);
        let [x1, y1] = self.scene_map.image_to_workspace(w, 0.0);
        [x0.min(x1), y0.min(y1), x0.max(x1), y0.max(y1)]
    }

    /// Check every field; the error names the field, its value and the allowed range.
    pub fn validate(&self) -> Result<(), ReliefParamsError> {
        let [x0, y0, x1, y1] = self.area_m();
        let smaller_side = (x1 - x0).min(y1 - y0);
        let err = |field, value, allowed| {
            Err(ReliefParamsError {
                field,
                value,
                allowed,
            })
        };
        if !(self.merge_distance_m > 0.0 && self.merge_distance_m < 0.25 * smaller_side) {
            return err(
                "merge_distance_m",
                self.merge_distance_m,
                "> 0 and < a quarter of the area's smaller side",
            );
        }
        if !(self.frame_width_m >= 0.0 && self.frame_width_m < 0.25 * smaller_side) {
            return err(
                "frame_width_m",
                self.frame_width_m,
                ">= 0 and < a quarter of the area's smaller side",
            );
        }
        if !(self.border_spacing_m > 0.0
            && self.border_spacing_m.is_finite()
            && self.border_spacing_m >= self.merge_distance_m)
        {
            return err(
                "border_spacing_m",
                self.border_spacing_m,
                "finite and >= merge_distance_m",
            );
        }
        if !(self.crossing_tolerance_m >= 0.0 && self.crossing_tolerance_m.is_finite()) {
            return err(
                "crossing_tolerance_m",
                self.crossing_tolerance_m,
                "finite and >= 0",
            );
        }
        if !(self.step_min_height_m > 0.0 && self.step_min_height_m.is_finite()) {
            return err(
                "step_min_height_m",
                self.step_min_height_m,
                "finite and > 0",
            );
        }
        if !(self.step_min_slope > 0.0 && self.step_min_slope.is_finite()) {
            return err("step_min_slope", self.step_min_slope, "finite and > 0");
        }
        if !(self.step_width_m > self.merge_distance_m
            && (self.frame_width_m == 0.0 || self.step_width_m < self.frame_width_m)
            && self.step_width_m < 0.25 * smaller_side)
        {
            return err(
                "step_width_m",
                self.step_width_m,
                "> merge_distance_m and < frame_width_m (when there is a frame)",
            );
        }
        if !(self.step_max_wall_slope > 0.0 && self.step_max_wall_slope.is_finite()) {
            return err(
                "step_max_wall_slope",
                self.step_max_wall_slope,
                "finite and > 0",
            );
        }
        if !(self.grid_cells_per_triangle > 0.0 && self.grid_cells_per_triangle <= 64.0) {
            return err(
                "grid_cells_per_triangle",
                self.grid_cells_per_triangle,
                "in (0, 64]",
            );
        }
        Ok(())
    }
}

/// A rejected build setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReliefParamsError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What is allowed.
    pub allowed: &'static str,
}

impl core::fmt::Display for ReliefParamsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "surface: {} = {} must be {}",
            self.field, self.value, self.allowed
        )
    }
}

/// Build settings for one camera view with the default device workspace: the image stretched
/// over a 40 x 30 cm area at the origin, 8 cm of relief in front of a back plane at 45 cm, and
/// the scene depth range spanning the segments' endpoints (nearest to farthest `Z` in front of
/// the camera). For tools that build a surface from a stereo pair without a rig configuration.
pub fn params_for_view(
    segments: &[SceneSegment3],
    image_size_px: [u32; 2],
) -> Result<ReliefParams, String> {
    let (mut near, mut far) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in segments {
        for z in [s.a_m[2], s.b_m[2]] {
            if z.is_finite() && z > 0.0 {
                near = near.min(z);
                far = far.max(z);
            }
        }
    }
    if !(near.is_finite() && far.is_finite()) {
        return Err("no segment endpoint in front of the camera: no scene depth range".into());
    }
    if far - near < 1e-6 * far {
        // A single depth: give the range some width so that it maps onto the front of the relief.
        far = near * 1.1;
    }
    let map = SceneMap::new(
        [0.0, 0.0],
        [0.4, 0.3],
        image_size_px,
        0.45,
        0.08,
        [near, far],
    )
    .map_err(|e| e.to_string())?;
    Ok(ReliefParams::new(map))
}
