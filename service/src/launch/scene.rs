//! The feed axis: what the control loop renders, built from the plan's [`PlannedFeed`] over the
//! area in front of the device: a wall, or a relief with the vision thread that keeps it up to
//! date (the box, a stereo pair, a folder of camera pairs, the device's cameras), the colour
//! under the finger where the scene has an image, and what the service says it runs.

use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use tracing::{info, warn};
use videt_config::Config;
use videt_relief::{ReliefLayout, ReliefModel};
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;
use videt_sim::{Vec3, VirtualOperator};

use super::LaunchError;
use crate::camera_feed::start_camera_feed;
use crate::colour_thread::{ColourOutputs, ColourSource};
use crate::plan::PlannedFeed;
use crate::relief_scene::{
    box_operator, box_relief, spawn_box_rebuilds, sweep_operator, SweepPath,
};
use crate::run::SceneLinks;
use crate::scene_feed::SceneFeed;

/// A scene ready to render: its feed, what it adds to the service, the colour under the
/// finger, what it is, and the relief the twin's operator explores.
pub struct Scene {
    /// What the control loop renders.
    pub feed: SceneFeed,
    /// What the service runs, for the session log (`None` for a wall: the hardware says it).
    pub description: Option<String>,
    /// The vision thread's links to the service (thimble, status, stall, live image).
    pub links: SceneLinks,
    /// The colour under the finger (`None`: off).
    pub colour: Option<ColourSource>,
    /// What the twin's operator explores.
    explored: Explored,
}

/// What the twin's virtual operator explores.
enum Explored {
    /// The wall it was built touching (its operator stays).
    Wall,
    /// The box, pressed onto and slid off.
    Box(ReliefLayout),
    /// A relief, swept across.
    Relief(ReliefLayout, Box<ReliefModel>),
}

impl Scene {
    /// The operator who explores this scene from `start_m` along `sweep`; `None` for a wall
    /// (the twin's own operator touches it).
    pub fn operator(&self, start_m: Vec3, sweep: &SweepPath) -> Option<VirtualOperator> {
        match &self.explored {
            Explored::Wall => None,
            Explored::Box(layout) => Some(box_operator(layout, start_m, 6.0)),
            Explored::Relief(layout, model) => {
                Some(sweep_operator(layout, model, start_m, sweep).0)
            }
        }
    }
}

/// Build the scene `feed` names over `layout`; `describe` turns a relief scene's text into what
/// the service says it runs (naming the device and the hardware). A camera folder's colour goes
/// to `colour_outputs`.
pub fn build(
    config: &Config,
    feed: PlannedFeed,
    layout: ReliefLayout,
    colour_outputs: ColourOutputs,
    describe: &dyn Fn(&str) -> String,
) -> Result<Scene, LaunchError> {
    match feed {
        PlannedFeed::Wall { instead_of_cameras } => {
            if let Some(why) = instead_of_cameras {
                warn!(
                    wall_z_m = setup::CHECK_WALL_Z_M,
                    "the check wall is rendered instead of the scene: {why}"
                );
            }
            Ok(wall())
        }
        PlannedFeed::Box => box_scene(config, layout, describe),
        PlannedFeed::Stereo(pair) => stereo_scene(config, pair, layout, describe),
        PlannedFeed::CameraFolder { dir, source, rig } => {
            let feed = start_camera_feed(
                config,
                source,
                dir.display().to_string(),
                rig,
                layout,
                colour_outputs,
            )
            .map_err(|e| LaunchError::failed(format!("camera scene: {e}")))?;
            info!(
                "digital twin: a virtual operator sweeping across the relief of a camera's pairs"
            );
            let what = describe(&format!(
                "digital twin: a virtual operator sweeping across the relief of the camera pairs in {}",
                dir.display()
            ));
            Ok(feed.into_scene(layout, Some(what)))
        }
        PlannedFeed::Cameras(rig) => {
            match crate::camera_feed::device_cameras(config, rig, layout) {
                Ok(feed) => Ok(feed.into_scene(layout, None)),
                Err(why) => {
                    warn!(
                        wall_z_m = setup::CHECK_WALL_Z_M,
                        "the check wall is rendered instead of the scene: {why}"
                    );
                    Ok(wall())
                }
            }
        }
    }
}

/// The check wall: a flat virtual wall in front of the frame.
fn wall() -> Scene {
    Scene {
        feed: SceneFeed::Wall(FixedSurface(setup::check_wall())),
        description: None,
        links: SceneLinks::default(),
        colour: None,
        explored: Explored::Wall,
    }
}

/// The bas-relief box: built now, rebuilt every second on a vision thread (which
/// `sim-fault vision-stall` holds back, a stalled camera).
fn box_scene(
    config: &Config,
    layout: ReliefLayout,
    describe: &dyn Fn(&str) -> String,
) -> Result<Scene, LaunchError> {
    let (model, report) =
        box_relief(&layout, 0.0).map_err(|e| LaunchError::failed(format!("surface: {e}")))?;
    let what = describe(
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge",
    );
    info!(
        vertices = report.vertices,
        triangles = report.triangles,
        constraints = report.constraints_kept,
        build_us = (report.timings.cleaning
            + report.timings.crossings
            + report.timings.triangulation
            + report.timings.model)
            .as_micros() as u64,
        "{what}"
    );
    let (writer, feed) = crate::relief_feed::relief_channel_for(config, model)
        .map_err(|e| LaunchError::failed(e.to_string()))?;
    let stall = Arc::new(AtomicBool::new(false));
    spawn_box_rebuilds(
        layout,
        writer,
        Arc::clone(&stall),
        videt_runtime::rt::vision_fifo_priority(&config.realtime),
    )
    .map_err(|e| LaunchError::failed(format!("cannot start the vision thread: {e}")))?;
    Ok(Scene {
        feed: SceneFeed::Relief(Box::new(feed)),
        description: Some(what),
        links: SceneLinks {
            vision_stall: Some(stall),
            ..SceneLinks::default()
        },
        colour: None,
        explored: Explored::Box(layout),
    })
}

/// The bas-relief of a stereo pair: the pipeline and the surface builder now, then live region
/// updates around the finger on a vision thread, rendered through the proxy with blended
/// swaps.
fn stereo_scene(
    config: &Config,
    pair: crate::stereo_relief::StereoPair,
    layout: ReliefLayout,
    describe: &dyn Fn(&str) -> String,
) -> Result<Scene, LaunchError> {
    use crate::stereo_relief::{spawn_live_updates, LiveSettings, LiveStats, StereoRelief};
    let name = pair.name.clone();
    let live = LiveSettings {
        checks: crate::stereo_relief::match_checks(&config.vision),
        patch_spacing_px: config.vision.patch_spacing_px,
        ..LiveSettings::default()
    };
    let (relief, model, initial) = StereoRelief::build(pair, &layout, live)
        .map_err(|e| LaunchError::failed(format!("stereo scene: {e}")))?;
    info!(
        pair = %name,
        matches = initial.matches,
        segments_3d = initial.segments_3d,
        constraints = initial.report.constraints_kept,
        rejected = initial.report.rejections.len(),
        depth_range_m = ?initial.depth_range_m,
        triangles = initial.report.triangles,
        pipeline_ms = initial.pipeline_time.as_secs_f64() * 1e3,
        build_ms = initial.build_time.as_secs_f64() * 1e3,
        "digital twin: the bas-relief of a real stereo pair, a virtual operator sweeping across it, live updates around the finger at {:.0} Hz",
        1.0 / live.update_period_s
    );
    let (writer, feed) = crate::relief_feed::relief_channel_for(config, model.clone())
        .map_err(|e| LaunchError::failed(e.to_string()))?;
    let stats = Arc::new(LiveStats::default());
    let status = Arc::clone(&stats);
    let (links, thimble_reader) = SceneLinks::following_the_finger(move || status.status_text());
    let keepalive_s = (config.vision.surface_max_age_s / 4.0).max(0.05);
    spawn_live_updates(
        relief,
        model.clone(),
        writer,
        thimble_reader,
        stats,
        keepalive_s,
        videt_runtime::rt::vision_fifo_priority(&config.realtime),
    )
    .map_err(|e| LaunchError::failed(format!("cannot start the vision thread: {e}")))?;
    Ok(Scene {
        feed: SceneFeed::Relief(Box::new(feed)),
        description: Some(describe(&format!(
            "digital twin: a virtual operator sweeping across the bas-relief of the stereo pair {name}"
        ))),
        links,
        colour: None,
        explored: Explored::Relief(layout, Box::new(model)),
    })
}

impl crate::camera_feed::CameraFeed {
    /// The scene of a camera's relief over `layout`, described as `description`.
    fn into_scene(self, layout: ReliefLayout, description: Option<String>) -> Scene {
        Scene {
            feed: SceneFeed::Relief(Box::new(self.feed)),
            description,
            links: self.links,
            colour: self.colour,
            explored: Explored::Relief(layout, Box::new(self.first)),
        }
    }
}
