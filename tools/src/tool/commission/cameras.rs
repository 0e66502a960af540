//! The cameras' part of the commissioning check: frames at the size the stereo calibration is
//! for and at the configured rate, and left and right not swapped.
//!
//! Which camera is which is told by the sign of the disparities: rectified with the installed
//! calibration, a pair in the right order has its matches at positive disparities (a point
//! further left in the right image), so the matcher, which searches positive disparities, finds
//! many matches in the pair as given and few with the two images exchanged; swapped cameras
//! give the opposite. A scene with too little texture to tell is reported as such.

use std::time::Duration;

use videt_config::edit::{Fix, FixValue};
use videt_config::Config;
use videt_hal::{GrayFrame, StereoCamera, StereoFrame};
use videt_service::camera_relief::CalibratedRig;
use videt_service::init::commission::StepReport;
use videt_vision::gray::GrayView;
use videt_vision::pipeline::{StereoPipeline, VisionParams};

/// Pairs captured to measure the frame rate.
const PAIRS: usize = 12;

/// The last pairs captured, whose matches tell the order.
const ORDER_PAIRS: usize = 4;

/// The matches found in one order must outnumber the other's this many times to tell.
const ORDER_RATIO: usize = 2;

/// The fewest matches that tell an order.
const MIN_MATCHES: usize = 20;

/// A camera whose left and right come swapped (the twin's cameras built the other way).
pub struct Swapped<C>(pub C);

impl<C: StereoCamera> videt_hal::ErrorType for Swapped<C> {
    type Error = C::Error;
}

impl<C: StereoCamera> StereoCamera for Swapped<C> {
    fn capture(&mut self, out: &mut StereoFrame) -> Result<(), Self::Error> {
        self.0.capture(out)?;
        std::mem::swap(&mut out.left, &mut out.right);
        std::mem::swap(&mut out.left_stamp, &mut out.right_stamp);
        // The colour comes from the camera configured as left: now the other one, unseen.
        out.left_rgb = None;
        Ok(())
    }
}

/// Where the pairs come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The cameras themselves: their frame rate is measured.
    Cameras,
    /// Files played as the cameras (the twin): the rate is the player's, not measured.
    Files,
}

/// The cameras' steps: `camera` gives the pairs of `config.vision.devices` (named `name`),
/// `rig` is the installed calibration.
pub fn check<C: StereoCamera>(
    camera: &mut C,
    rig: &CalibratedRig,
    config: &Config,
    name: &str,
    source: Source,
) -> Vec<StepReport>
where
    C::Error: std::fmt::Display,
{
    let mut frame = StereoFrame::default();
    let mut stamps = Vec::with_capacity(PAIRS);
    let mut last = Vec::with_capacity(ORDER_PAIRS);
    for n in 0..PAIRS {
        if let Err(e) = camera.capture(&mut frame) {
            return vec![StepReport::fail(
                "cameras.frames",
                format!("no frames from {name}: {e}"),
                Vec::new(),
            )
            .with_wiring("check the cameras' cables and vision.devices (left, right)")];
        }
        stamps.push(frame.left_stamp);
        if n + ORDER_PAIRS >= PAIRS {
            last.push(frame.clone());
        }
    }
    let (w, h) = (frame.left.width, frame.left.height);
    let span = stamps[PAIRS - 1].nanos_since(stamps[0]);
    let rate_hz = (PAIRS - 1) as f64 / Duration::from_nanos(span.max(1)).as_secs_f64();
    let wanted = f64::from(config.vision.frame_rate_hz);
    let frames = format!(
        "{name}: {w}x{h} px at {rate_hz:.1} frames/s (vision.frame_rate_hz = {})",
        config.vision.frame_rate_hz
    );
    let mut steps = vec![if source == Source::Files {
        StepReport::pass(
            "cameras.frames",
            format!("{name}: {w}x{h} px (played from files: the rate is not measured)"),
        )
    } else if (rate_hz / wanted - 1.0).abs() <= 0.15 {
        StepReport::pass("cameras.frames", frames)
    } else {
        StepReport::fail(
            "cameras.frames",
            format!("{frames}: not the configured rate"),
            vec![Fix::new(
                "vision.frame_rate_hz",
                None,
                FixValue::Integer(rate_hz.round().max(1.0) as i64),
            )],
        )
    }];
    let [cw, ch] = rig.size_px;
    if (cw, ch) != (w, h) {
        steps.push(
            StepReport::fail(
                "cameras.calibration-size",
                format!(
                    "the calibration ({}) is for {cw}x{ch} px, the cameras give {w}x{h} px",
                    config.vision.stereo_calibration
                ),
                Vec::new(),
            )
            .with_wiring("calibrate the cameras at the size they give (videt calibrate-stereo), or set them to the calibration's"),
        );
        steps.push(StepReport::skipped(
            "cameras.order",
            "not checked: the frames cannot be rectified with this calibration",
        ));
        return steps;
    }
    steps.push(StepReport::pass(
        "cameras.calibration-size",
        format!("the calibration is for the {w}x{h} px the cameras give"),
    ));
    steps.push(order(&last, rig, config));
    steps
}

/// Which camera is which, from the pairs `frames`: their matches rectified and matched as
/// given, and with the two images taken the other way round (each rectified with the other
/// camera's tables); the right order has its matches at positive disparities.
fn order(frames: &[StereoFrame], rig: &CalibratedRig, config: &Config) -> StepReport {
    let name = "cameras.order";
    let mut params = VisionParams::default();
    params.matching.disparity_max_px = config.vision.max_disparity_px as f32;
    let mut pipeline = StereoPipeline::new();
    let mut matches = |pair: &StereoFrame| -> Result<usize, String> {
        let blank = || GrayFrame {
            width: pair.left.width,
            height: pair.left.height,
            data: vec![0; pair.left.data.len()],
        };
        let (mut left, mut right) = (blank(), blank());
        rig.rectifier
            .apply(pair, &mut left, &mut right)
            .map_err(|e| e.to_string())?;
        let l = GrayView::new(&left.data, left.width as usize, left.height as usize)
            .map_err(|e| e.to_string())?;
        let r = GrayView::new(&right.data, right.width as usize, right.height as usize)
            .map_err(|e| e.to_string())?;
        Ok(pipeline
            .run(&l, &r, None, &params)
            .map_or(0, |o| o.matches.len()))
    };
    let (mut given, mut exchanged) = (0, 0);
    for frame in frames {
        let other_way = StereoFrame {
            left: frame.right.clone(),
            right: frame.left.clone(),
            ..StereoFrame::default()
        };
        match (matches(frame), matches(&other_way)) {
            (Ok(g), Ok(e)) => (given, exchanged) = (given + g, exchanged + e),
            (Err(e), _) | (_, Err(e)) => {
                return StepReport::fail(
                    name,
                    format!("a pair cannot be rectified: {e}"),
                    Vec::new(),
                )
            }
        }
    }
    let measured = format!(
        "{given} matches at positive disparities in the last {} pairs as given, {exchanged} with left and right exchanged",
        frames.len()
    );
    let devices = &config.vision.devices;
    if given >= MIN_MATCHES && given >= ORDER_RATIO * exchanged {
        StepReport::pass(name, format!("{measured}: left is left"))
    } else if exchanged >= MIN_MATCHES && exchanged >= ORDER_RATIO * given {
        StepReport::fail(
            name,
            format!("{measured}: the cameras are swapped"),
            vec![Fix::new(
                "vision.devices",
                None,
                FixValue::List(vec![
                    FixValue::Text(devices[1].clone()),
                    FixValue::Text(devices[0].clone()),
                ]),
            )],
        )
    } else {
        StepReport::skipped(
            name,
            format!("{measured}: too few to tell; point the cameras at a textured scene about a metre away and run the check again"),
        )
    }
}
