//! The mapping between the device workspace and the camera image / scene depth.
//!
//! The explorable area is a rectangle in the device's `x`-`y` directions; the left camera's image
//! is stretched onto it (image `u` grows with `x`, image `v` grows downwards, i.e. with `-y`).
//! Scene depth `Z` (distance from the cameras) maps into the bas-relief's depth range along the
//! reference normal: the nearest scene depth stands out most towards the user (smallest device
//! `z`), the farthest lies on the back plane `z = back_plane_z_m`.

/// Workspace ↔ image and scene-depth ↔ relief mapping. Plain data, validated by [`SceneMap::new`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneMap {
    area_origin_m: [f64; 2],
    area_size_m: [f64; 2],
    image_size_px: [f64; 2],
    back_plane_z_m: f64,
    relief_depth_m: f64,
    scene_depth_range_m: [f64; 2],
}

/// A rejected scene map: which field, and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneMapError {
    /// The offending field.
    pub field: &'static str,
    /// What is allowed.
    pub allowed: &'static str,
}

impl core::fmt::Display for SceneMapError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "scene map: {} must be {}", self.field, self.allowed)
    }
}

impl SceneMap {
    /// Build a mapping.
    /// - `area_origin_m`: device `(x, y)` of the image's bottom-left corner, metres;
    /// - `area_size_m`: width and height of the explorable area, metres (> 0);
    /// - `image_size_px`: image width and height, pixels (> 0);
    /// - `back_plane_z_m`: device `z` of the relief's back plane (far scene), metres (> 0);
    /// - `relief_depth_m`: the bas-relief range `d_max`, metres (> 0, < `back_plane_z_m`);
    /// - `scene_depth_range_m`: nearest and farthest scene depth mapped, metres (0 < near < far).
    pub fn new(
        area_origin_m: [f64; 2],
        area_size_m: [f64; 2],
        image_size_px: [u32; 2],
        back_plane_z_m: f64,
        relief_depth_m: f64,
        scene_depth_range_m: [f64; 2],
    ) -> Result<SceneMap, SceneMapError> {
        let finite = |v: f64| v.is_finite();
        if !(finite(area_origin_m[0]) && finite(area_origin_m[1])) {
            return Err(SceneMapError {
                field: "area_origin_m",
                allowed: "finite",
            });
        }
        if !(area_size_m[0] > 0.0
            && area_size_m[1] > 0.0
            && finite(area_size_m[0])
            && finite(area_size_m[1]))
        {
            return Err(SceneMapError {
                field: "area_size_m",
                allowed: "finite and > 0",
            });
        }
        if image_size_px[0] == 0 || image_size_px[1] == 0 {
            return Err(SceneMapError {
                field: "image_size_px",
                allowed: "> 0",
            });
        }
        if !(back_plane_z_m > 0.0 && finite(back_plane_z_m)) {
            return Err(SceneMapError {
                field: "back_plane_z_m",
                allowed: "finite and > 0",
            });
        }
        if !(relief_depth_m > 0.0 && relief_depth_m < back_plane_z_m) {
            return Err(SceneMapError {
                field: "relief_depth_m",
                allowed: "> 0 and < back_plane_z_m",
            });
        }
        let [near, far] = scene_depth_range_m;
        if !(near > 0.0 && far > near && finite(far)) {
            return Err(SceneMapError {
                field: "scene_depth_range_m",
                allowed: "0 < near < far, finite",
            });
        }
        Ok(SceneMap {
            area_origin_m,
            area_size_m,
            image_size_px: [image_size_px[0] as f64, image_size_px[1] as f64],
            back_plane_z_m,
            relief_depth_m,
            scene_depth_range_m,
        })
    }

    /// Image size, pixels.
    pub fn image_size_px(&self) -> [f64; 2] {
        self.image_size_px
    }

    /// Device `z` of the back plane, metres.
    pub fn back_plane_z_m(&self) -> f64 {
        self.back_plane_z_m
    }

    /// The relief range `d_max`, metres.
    pub fn relief_depth_m(&self) -> f64 {
        self.relief_depth_m
    }

    /// Image pixel `(u, v)` (may lie outside the image) under the device point `(x, y)`.
    pub fn workspace_to_image(&self, x_m: f64, y_m: f64) -> [f64; 2] {
        let s = (x_m - self.area_origin_m[0]) / self.area_size_m[0];
        let t = (y_m - self.area_origin_m[1]) / self.area_size_m[1];
        [s * self.image_size_px[0], (1.0 - t) * self.image_size_px[1]]
    }

    /// Device `(x, y)` under the image pixel `(u, v)`.
    pub fn image_to_workspace(&self, u_px: f64, v_px: f64) -> [f64; 2] {
        let s = u_px / self.image_size_px[0];
        let t = 1.0 - v_px / self.image_size_px[1];
        [
            self.area_origin_m[0] + s * self.area_size_m[0],
            self.area_origin_m[1] + t * self.area_size_m[1],
        ]
    }

    /// Device `z` of the relief for a scene depth (clamped to the mapped range): the nearest depth
    /// gives `back_plane_z_m - relief_depth_m`, the farthest `back_plane_z_m`.
    pub fn scene_depth_to_relief_z(&self, scene_depth_m: f64) -> f64 {
        let [near, far] = self.scene_depth_range_m;
        let d = if scene_depth_m.is_finite() {
            scene_depth_m.clamp(near, far)
        } else {
            far
        };
        let farness = (d - near) / (far - near);
        self.back_plane_z_m - self.relief_depth_m * (1.0 - farness)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_orientation() {
        let m = SceneMap::new([0.0, 0.0], [0.4, 0.3], [640, 480], 0.45, 0.08, [0.5, 5.0]).unwrap();
        let [u, v] = m.workspace_to_image(0.1, 0.2);
        let [x, y] = m.image_to_workspace(u, v);
        assert!((x - 0.1).abs() < 1e-12 && (y - 0.2).abs() < 1e-12);
        assert_eq!(
            m.workspace_to_image(0.0, 0.0),
            [0.0, 480.0],
            "bottom-left corner"
        );
        assert!((m.scene_depth_to_relief_z(0.5) - 0.37).abs() < 1e-12);
        assert!((m.scene_depth_to_relief_z(50.0) - 0.45).abs() < 1e-12);
        assert_eq!(m.scene_depth_to_relief_z(f64::NAN), 0.45);
    }

    #[test]
    fn invalid_fields_are_named() {
        let e =
            SceneMap::new([0.0, 0.0], [0.0, 0.3], [640, 480], 0.45, 0.08, [0.5, 5.0]).unwrap_err();
        assert_eq!(e.field, "area_size_m");
        let e =
            SceneMap::new([0.0, 0.0], [0.4, 0.3], [640, 480], 0.45, 0.5, [0.5, 5.0]).unwrap_err();
        assert_eq!(e.field, "relief_depth_m");
    }
}
