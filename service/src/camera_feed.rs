//! A relief feed from cameras: the device's V4L2 stereo pair, or a folder of raw pairs played as
//! one on the twin. The first relief is built before the service starts; a vision thread
//! ([`crate::camera_relief`]) keeps it up to date, and the colour under the finger comes from
//! the same left frames.

use tracing::{info, warn};
use videt_config::Config;
use videt_relief::ReliefLayout;

use crate::camera_relief::CalibratedRig;
use crate::colour_thread::{ColourOutputs, ColourSource};
use crate::relief_feed::ReliefFeed;
use crate::run::SceneLinks;

/// The device's cameras (`vision.devices`) feeding reliefs over `layout`, rectified by `rig`
/// (`vision.stereo_calibration`); why not, when they cannot.
pub fn device_cameras(
    config: &Config,
    rig: CalibratedRig,
    layout: ReliefLayout,
) -> Result<CameraFeed, String> {
    #[cfg(feature = "v4l")]
    {
        use videt_drivers::camera::v4l_stereo::{V4lStereo, V4lStereoConfig};
        let [left, right] = &config.vision.devices;
        let camera = V4lStereo::open(&V4lStereoConfig {
            left: left.into(),
            right: right.into(),
            width: rig.size_px[0],
            height: rig.size_px[1],
            pair_tolerance: std::time::Duration::from_secs_f64(
                config.vision.pair_tolerance_ms / 1e3,
            ),
            timeout: std::time::Duration::from_secs(1),
            buffers: 4,
            frame_rate_hz: config.vision.frame_rate_hz,
            prefer_colour: config.colour.enabled,
        })
        .map_err(|e| format!("cameras (vision.devices): {e}"))?;
        let vibrotactors = ColourOutputs::Gpio {
            chip: config.sensors.gpio_chip.clone(),
            lines: config.sensors.vibrotactor_lines,
        };
        start_camera_feed(
            config,
            camera,
            format!("cameras {left} + {right}"),
            rig,
            layout,
            vibrotactors,
        )
    }
    #[cfg(not(feature = "v4l"))]
    {
        // The plan chooses the cameras only in a build that captures them.
        let _ = (config, rig, layout);
        Err(
            "this videtd is built without V4L2 capture (cargo build --release --features v4l)"
                .into(),
        )
    }
}

/// A relief feed from a camera.
pub struct CameraFeed {
    /// What the control loop renders.
    pub feed: ReliefFeed,
    /// The camera thread's links to the service (the thimble it looks at, its counters on the
    /// status line, the live image).
    pub links: SceneLinks,
    /// The first relief.
    pub first: videt_relief::ReliefModel,
    /// The colour under the finger from the camera's left frames.
    pub colour: Option<ColourSource>,
}

/// Build the first relief from `camera` (rectified by `rig`) over the area of `layout`, open
/// the relief channel and start the thread that keeps it up to date
/// (`camera_relief::spawn_camera_updates`).
pub fn start_camera_feed<C>(
    config: &Config,
    camera: C,
    name: String,
    rig: CalibratedRig,
    layout: ReliefLayout,
    colour_outputs: ColourOutputs,
) -> Result<CameraFeed, String>
where
    C: videt_hal::StereoCamera + Send + 'static,
{
    use crate::camera_relief::{spawn_camera_updates, CameraRelief, CameraSchedule, CameraStats};
    use std::sync::atomic::AtomicBool;
    use std::sync::Arc;
    // The colour under the finger, from the same left frames, mapped as the relief is.
    let colour = crate::colour_thread::colour_enabled(config).then(|| {
        crate::colour_thread::camera_colour(&layout, rig.size_px, &config.colour, colour_outputs)
    });
    let (colour, colour_frames) = match colour {
        Some(Ok((source, writer))) => (Some(source), Some(writer)),
        Some(Err(e)) => {
            warn!("colour rendering disabled: {e}");
            (None, None)
        }
        None => (None, None),
    };
    let mut relief = CameraRelief::new(
        camera,
        name.clone(),
        rig,
        config.vision.max_disparity_px as f32,
        layout,
    )?;
    if let Some(writer) = colour_frames {
        relief = relief.with_colour(writer);
    }
    let live_image = config
        .live
        .enabled
        .then(|| Arc::new(videt_viewers::live::ImageSlot::default()));
    if let Some(slot) = &live_image {
        relief = relief.with_live_image(Arc::clone(slot));
    }
    let checks = crate::stereo_relief::match_checks(&config.vision);
    relief = relief.with_live_settings(crate::stereo_relief::LiveSettings {
        update_period_s: 1.0 / f64::from(config.vision.frame_rate_hz.max(1)),
        checks,
        patch_spacing_px: config.vision.patch_spacing_px,
        ..Default::default()
    });
    let (model, first) = relief.rebuild()?;
    info!(
        camera = %name,
        checks_against_wrong_matches = %checks,
        matches = first.matches,
        segments_3d = first.segments_3d,
        depth_range_m = ?first.depth_range_m,
        triangles = first.report.triangles,
        pipeline_ms = first.pipeline_time.as_secs_f64() * 1e3,
        build_ms = first.build_time.as_secs_f64() * 1e3,
        "relief from the cameras: updated around the finger every frame while it is over the scene (whole image every {} s), whole image every {} s while it is not",
        config.vision.full_refresh_s,
        config.vision.rebuild_period_s
    );
    let (writer, feed) =
        crate::relief_feed::relief_channel_for(config, model.clone()).map_err(|e| e.to_string())?;
    let stats = Arc::new(CameraStats::default());
    let status = Arc::clone(&stats);
    let (mut links, thimble_reader) =
        SceneLinks::following_the_finger(move || status.status_text());
    links.live_image = live_image;
    // The thread runs as long as the process: the service ends by exiting.
    let stop = Arc::new(AtomicBool::new(false));
    spawn_camera_updates(
        relief,
        writer,
        CameraSchedule {
            rebuild_period: std::time::Duration::from_secs_f64(config.vision.rebuild_period_s),
            full_refresh: std::time::Duration::from_secs_f64(config.vision.full_refresh_s),
        },
        Some(thimble_reader),
        stats,
        stop,
        videt_runtime::rt::vision_fifo_priority(&config.realtime),
    )
    .map_err(|e| format!("cannot start the vision thread: {e}"))?;
    Ok(CameraFeed {
        feed,
        links,
        first: model,
        colour,
    })
}
