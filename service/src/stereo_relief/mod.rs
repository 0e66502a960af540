//! The bas-relief from a real stereo pair, kept up to date around the finger.
//!
//! [`StereoRelief`] runs the stereo pipeline (rectified mode: Canny, segments, Ayache matching,
//! back-projection) on a pair, maps the 3D segments into the device workspace with a
//! [`ReliefLayout`](videt_relief::ReliefLayout) and builds the relief with the surface builder.
//! Then, given the thimble's position and velocity, it re-matches only the image region of
//! interest under the finger (the pipeline's local mode), replaces the segments inside that
//! region with the fresh ones ([`merge_region`](videt_relief::region::merge_region)) and
//! rebuilds the relief: the live update the vision thread publishes.
//!
//! The scene depth range mapped onto the relief depth is fixed at the first build (robust
//! percentiles of the segments' depths, so a few wrong matches do not flatten the relief), so
//! that a live update never rescales the whole relief.
//!
//! The demo pair ([`StereoPair::demo`]) is compiled in: Middlebury's "tsukuba" pair
//! (`assets/demo-stereo/`, attribution there).
//!
//! The pairs and their cameras are in `pair`; the segments' mapping onto the relief, used with
//! or without a [`StereoRelief`], in `mapping`; the relief of a pair and its whole-image builds
//! in `relief`; the updates around the finger and the vision thread in `live`.

mod live;
mod mapping;
mod pair;
mod relief;

pub use live::{spawn_live_updates, LiveStats, RegionUpdate};
pub use mapping::{
    check_view_relief_depth, pinhole, reason_label, report_text, scene_depth_range, scene_segments,
    view_params, VIEW_AREA_WIDTH_M, VIEW_BACK_PLANE_Z_M,
};
pub use pair::{PairCamera, StereoPair, DEMO_CAMERA_TOML, DEMO_LEFT_PNG, DEMO_RIGHT_PNG};
pub use relief::{
    match_checks, InitialBuild, LiveSettings, StereoRelief, DEFAULT_PATCH_SPACING_PX,
};
