//! The twin's bas-relief demonstration: a box on a back plane, built from known segments with
//! the real surface builder, in front of the configured rig; and a virtual operator who presses
//! onto the box top, slides off its edge down onto the base and climbs back.

use videt_control::blend::BlendParams;
use videt_control::proxy::ProxyParams;
use videt_control::SceneMap;
use videt_rt_config::Config;
use videt_sim::{Vec3, VirtualOperator, Waypoint};
use videt_vision::surface::{
    build_from_device, BuildError, BuildReport, DeviceSegment, ReliefModel, ReliefParams,
};

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
}

impl ReliefLayout {
    /// A 20 x 15 cm area centred in front of the configured guides, back plane at 36 cm, 4 cm
    /// of relief.
    pub fn for_config(config: &Config) -> ReliefLayout {
        let g = &config.rig.guides_m;
        ReliefLayout {
            centre_m: [
                (g[0][0] + g[1][0] + g[2][0]) / 3.0,
                (g[0][1] + g[1][1] + g[2][1]) / 3.0,
            ],
            size_m: [0.20, 0.15],
            back_plane_z_m: 0.36,
            relief_depth_m: 0.04,
        }
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
        Ok(ReliefParams::new(map))
    }
}

/// The demo box's segments (device coordinates), centred on the area: a 5 x 5 cm top at
/// `z = 0.335 - lift_m` and a 9 x 9 cm base outline at `z = 0.352`.
pub fn box_segments(layout: &ReliefLayout, lift_m: f64) -> Vec<DeviceSegment> {
    let [cx, cy] = layout.centre_m;
    let square = |half: f64, z: f64| {
        let c = [
            [cx - half, cy - half],
            [cx + half, cy - half],
            [cx + half, cy + half],
            [cx - half, cy + half],
        ];
        (0..4)
            .map(|k| DeviceSegment {
                a_m: [c[k][0], c[k][1], z],
                b_m: [c[(k + 1) % 4][0], c[(k + 1) % 4][1], z],
            })
            .collect::<Vec<_>>()
    };
    let mut segs = square(0.025, 0.335 - lift_m);
    segs.extend(square(0.045, 0.352));
    segs
}

/// Build the demo box relief.
pub fn box_relief(
    layout: &ReliefLayout,
    lift_m: f64,
) -> Result<(ReliefModel, BuildReport), BuildError> {
    let params = layout
        .params([640, 480], [0.5, 5.0])
        .map_err(BuildError::Triangulation)?;
    build_from_device(&box_segments(layout, lift_m), &[], &params)
}

/// Proxy settings of the demo: light friction.
pub fn proxy_params() -> ProxyParams {
    ProxyParams {
        static_friction: 0.2,
        dynamic_friction: 0.15,
        ..ProxyParams::default()
    }
}

/// Blend settings of the demo: at least 0.1 s, at most 0.05 N per period from a swap.
pub fn blend_params(config: &Config) -> BlendParams {
    BlendParams {
        blend_time_s: 0.1,
        max_step_n: 0.05,
        stale_after_s: config.vision.surface_max_age_s.max(1e-3),
        fade_time_s: config.vision.surface_fade_s.max(1e-3),
    }
}

/// A virtual operator starting at `start_m` who presses onto the box top (aiming at the back
/// plane), slides 8 cm along `x` off the box's edge onto the base, and climbs back, every
/// `period_s` seconds (at least 5).
pub fn box_operator(layout: &ReliefLayout, start_m: Vec3, period_s: f64) -> VirtualOperator {
    let [cx, cy] = layout.centre_m;
    let press = Vec3::new(cx, cy, layout.back_plane_z_m);
    let wp = |time_s: f64, target_m: Vec3| Waypoint { time_s, target_m };
    VirtualOperator::new(
        vec![
            wp(0.0, start_m),
            wp(0.8, press),
            wp(2.3, press + Vec3::new(0.08, 0.0, 0.0)),
            wp(3.8, press),
            wp(4.5, press),
            wp(5.0, start_m),
        ],
        200.0,
        6.0,
    )
    .repeating(period_s.max(5.0))
}
