//! Where the relief sits in front of the rig: the explorable area, the back plane, the relief's
//! depth and shape, and the build settings they make for a camera.

use videt_control::SceneMap;

use crate::input::{ReliefParams, ReliefShape};

/// Where the relief sits in front of the rig.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReliefLayout {
    /// Centre of the explorable area, `(x, y)` metres.
    pub centre_m: [f64; 2],
    /// Width and height of the area, metres.
    pub size_m: [f64; 2],
    /// Device `z` of the back plane, metres.
    pub back_plane_z_m: f64,
    /// Relief depth `d_max`, metres.
    pub relief_depth_m: f64,
    /// How the relief spans the gaps between the segments (`vision.relief_shape`).
    pub shape: ReliefShape,
}

impl ReliefLayout {
    /// A 20 x 15 cm area centred in front of `guides_m` (the centre of their `x`, `y`), back
    /// plane at 36 cm, 4 cm of relief, shaped `shape`.
    pub fn in_front_of(guides_m: &[[f64; 2]; 3], shape: ReliefShape) -> ReliefLayout {
        let g = guides_m;
        ReliefLayout {
            centre_m: [
                (g[0][0] + g[1][0] + g[2][0]) / 3.0,
                (g[0][1] + g[1][1] + g[2][1]) / 3.0,
            ],
            size_m: [0.20, 0.15],
            back_plane_z_m: 0.36,
            relief_depth_m: 0.04,
            shape,
        }
    }

    /// The same area centred at `centre_m` (`x`, `y`, metres): in front of another device's
    /// guides.
    pub fn centred_at(self, centre_m: [f64; 2]) -> ReliefLayout {
        ReliefLayout { centre_m, ..self }
    }

    /// The build settings for a camera of `image_size_px` seeing scene depths in
    /// `scene_depth_range_m` (metres).
    pub fn params(
        &self,
        image_size_px: [u32; 2],
        scene_depth_range_m: [f64; 2],
    ) -> Result<ReliefParams, String> {
        let map = SceneMap::new(
            [
                self.centre_m[0] - self.size_m[0] / 2.0,
                self.centre_m[1] - self.size_m[1] / 2.0,
            ],
            self.size_m,
            image_size_px,
            self.back_plane_z_m,
            self.relief_depth_m,
            scene_depth_range_m,
        )
        .map_err(|e| e.to_string())?;
        let mut params = ReliefParams::new(map);
        params.shape = self.shape;
        Ok(params)
    }
}
