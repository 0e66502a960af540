//! The colour thread of `videtd`: the colour under the thimble rendered as vibration
//! (paper §6.1).
//!
//! One thread runs the [`VibrationLoop`] at its tick (1.5 kHz by default, absolute-time sleeps)
//! and, every [`TICKS_PER_READING`] ticks, reads the latest thimble state (the control thread's
//! wait-free snapshot) and the latest colour frame (a snapshot too), samples the colour under the
//! thimble through the [`SceneMap`], quantizes it with hysteresis and hands the level triple to
//! the loop. The supervisor switches rendering off whenever the control loop is not in its normal
//! state or the service is stopping ([`ColourRuntime::supervise`]); the thread is silent too when
//! the finger is outside the image or no frame has arrived, and leaves every output off when it
//! stops. Nothing on this thread allocates after start-up.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use tracing::{error, info, warn};
use videt_colour::level::triple_letters;
use videt_colour::vibration_loop::VibrationError;
use videt_colour::{
    ColourReader, ColourSpace, Pattern, PatternConfig, PeriodJitter, QuantizerConfig,
    RecordingVibrotactors, SamplerConfig, VibrationInputs, VibrationLoop, WindowStatistic,
};
use videt_config::{ColourConfig, ColourSpaceName, ColourStatistic};
use videt_control::safety::SafetyState;
use videt_control::SceneMap;
use videt_hal::{Clock, RgbFrame, Vibrotactors};

use videt_runtime::cycle::CycleRecord;
use videt_runtime::rt::SystemClock;
use videt_runtime::snapshot::{snapshot_channel, SnapshotReader, SnapshotWriter};
use videt_runtime::thimble::ThimbleState;

/// The demonstration image `videtd --sim` renders: a crop of the Middlebury "cones" left image
/// (attribution in `assets/colour-demo/ATTRIBUTION.md`).
pub const DEMO_IMAGE_PNG: &[u8] = include_bytes!("../assets/colour-demo/cones-left-crop.png");

/// Vibration ticks between two colour readings (1.5 kHz / 25 = 60 readings per second).
pub const TICKS_PER_READING: u64 = 25;

/// Edges the twin's recording vibrotactors keep (about 7 minutes of three busy channels).
pub const TWIN_EDGE_CAPACITY: usize = 200_000;

/// What the status line shows: the colour the current levels came from.
#[derive(Debug, Default)]
pub struct ColourStatus {
    /// Bit 31: valid; bits 0..24: RGB.
    rgb: AtomicU32,
}

impl ColourStatus {
    fn set(&self, rgb: Option<[u8; 3]>) {
        let packed = rgb.map_or(0, |[r, g, b]| {
            1 << 31 | u32::from(r) << 16 | u32::from(g) << 8 | u32::from(b)
        });
        self.rgb.store(packed, Ordering::Relaxed);
    }
    /// The sampled colour under the thimble, if any.
    pub fn rgb(&self) -> Option<[u8; 3]> {
        let p = self.rgb.load(Ordering::Relaxed);
        (p & 1 << 31 != 0).then_some([(p >> 16) as u8, (p >> 8) as u8, p as u8])
    }
}

/// The shared state of a running colour thread.
#[derive(Debug, Clone)]
pub struct ColourHandles {
    /// The vibration loop's inputs (levels, active, shutdown).
    pub inputs: Arc<VibrationInputs>,
    /// The colour under the thimble, for the status line.
    pub status: Arc<ColourStatus>,
}

impl ColourHandles {
    /// `colour HLL rgb(230,  39,  59)`, `colour quiet (off-image)` or
    /// `colour quiet (not rendering)`.
    pub fn status_text(&self) -> String {
        match (
            self.inputs.is_active(),
            self.inputs.levels(),
            self.status.rgb(),
        ) {
            (true, Some(levels), Some([r, g, b])) => {
                let [lr, lg, lb] = triple_letters(levels);
                format!("colour {lr}{lg}{lb} rgb({r:3}, {g:3}, {b:3})")
            }
            (false, _, _) => "colour quiet (not rendering)".to_string(),
            _ => "colour quiet (off-image)".to_string(),
        }
    }
}

/// Settings of the colour thread.
#[derive(Debug, Clone, Copy)]
pub struct ColourSettings {
    /// Workspace ↔ image mapping (the bas-relief's).
    pub map: SceneMap,
    /// Sampling window.
    pub sampler: SamplerConfig,
    /// Thresholds and hysteresis.
    pub quantizer: QuantizerConfig,
    /// Carrier and duties.
    pub pattern: PatternConfig,
    /// Vibration ticks per carrier period.
    pub ticks_per_period: u32,
}

/// Why the colour thread could not start or stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ColourThreadError {
    /// A setting or the demo image was rejected.
    #[error("colour settings: {0}")]
    Config(String),
    /// A vibrotactor write failed (outputs were switched off).
    #[error(transparent)]
    Output(#[from] VibrationError),
}

fn config_error(e: impl std::fmt::Display) -> ColourThreadError {
    ColourThreadError::Config(e.to_string())
}

/// The scene map the twin's demonstration uses: a 0.20 m x 0.15 m area centred under the guide
/// points' centroid (where the virtual operator touches the wall and slides 8 cm in +x), over an
/// image of `image_size_px`, with the back plane at the demo wall.
pub fn demo_scene_map(
    guides_m: &[[f64; 2]; 3],
    wall_z_m: f64,
    image_size_px: [u32; 2],
) -> Result<SceneMap, videt_control::scene_map::SceneMapError> {
    let cx = (guides_m[0][0] + guides_m[1][0] + guides_m[2][0]) / 3.0;
    let cy = (guides_m[0][1] + guides_m[1][1] + guides_m[2][1]) / 3.0;
    let size = [0.20, 0.15];
    SceneMap::new(
        [cx - size[0] / 2.0, cy - size[1] / 2.0],
        size,
        image_size_px,
        wall_z_m,
        0.08_f64.min(wall_z_m / 2.0),
        [0.5, 5.0],
    )
}

/// Where the colour thread's vibration goes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColourOutputs {
    /// The twin's recording vibrotactors.
    Recording,
    /// The device's vibrotactors: three lines of a GPIO character device.
    Gpio {
        /// The chip, e.g. `/dev/gpiochip0` (`sensors.gpio_chip`).
        chip: String,
        /// Red, green and blue lines (`sensors.vibrotactor_lines`).
        lines: [u32; 3],
    },
}

/// The reading end of the colour frames a camera thread publishes, handed to the colour thread
/// once, when it starts.
#[derive(Clone, Default)]
pub struct CameraColourFrames(Arc<Mutex<Option<SnapshotReader<RgbFrame>>>>);

impl std::fmt::Debug for CameraColourFrames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CameraColourFrames")
    }
}

impl CameraColourFrames {
    /// A channel: the writer for the camera thread, this for the colour source. Until the
    /// camera publishes, the colour thread sees an empty frame (and stays quiet).
    pub fn channel() -> (SnapshotWriter<RgbFrame>, CameraColourFrames) {
        let (writer, reader) = snapshot_channel(RgbFrame::default());
        (
            writer,
            CameraColourFrames(Arc::new(Mutex::new(Some(reader)))),
        )
    }

    fn take(&self) -> Option<SnapshotReader<RgbFrame>> {
        self.0.lock().ok()?.take()
    }
}

/// What the colour thread renders from: the initial frame and the settings.
#[derive(Debug, Clone)]
pub struct ColourSource {
    /// The frame until a newer one is published (for the twin: the demo image).
    pub frame: RgbFrame,
    /// Sampling, quantization, pattern, mapping.
    pub settings: ColourSettings,
    /// Where the vibration goes.
    pub outputs: ColourOutputs,
    /// Frames a camera publishes (`None`: `frame` only, or what is published through
    /// [`ColourRuntime::frames`]).
    pub camera_frames: Option<CameraColourFrames>,
}

/// The colour source of a camera scene: the colour under the finger from the rectified left
/// camera frames the camera thread publishes on the returned writer, mapped to the workspace
/// as the camera's relief is (`layout` over images of `image_size_px`), sampled, quantized and
/// rendered as `colour` says.
pub fn camera_colour(
    layout: &videt_relief::ReliefLayout,
    image_size_px: [u32; 2],
    colour: &ColourConfig,
    outputs: ColourOutputs,
) -> Result<(ColourSource, SnapshotWriter<RgbFrame>), ColourThreadError> {
    // The scene depth range does not enter the workspace-to-image mapping.
    let map = layout
        .params(image_size_px, [0.5, 5.0])
        .map_err(config_error)?
        .scene_map;
    let (writer, frames) = CameraColourFrames::channel();
    let source = ColourSource {
        frame: RgbFrame::default(),
        settings: ColourSettings::from_config(map, colour)?,
        outputs,
        camera_frames: Some(frames),
    };
    Ok((source, writer))
}

/// Vibration ticks per carrier period: 1.5 kHz at the paper's 75 Hz, and duties in steps of 5 %.
pub const TICKS_PER_PERIOD: u32 = 20;

/// The sampling window and the quantizer the `[colour]` configuration section describes.
pub fn colour_levels(colour: &ColourConfig) -> (SamplerConfig, QuantizerConfig) {
    let sampler = SamplerConfig {
        window_px: colour.window_px,
        statistic: match colour.statistic {
            ColourStatistic::Median => WindowStatistic::Median,
            ColourStatistic::Mean => WindowStatistic::Mean,
        },
    };
    let space = match colour.space {
        ColourSpaceName::Chromaticity => ColourSpace::Chromaticity {
            black_level: colour.black_level as f32,
            white_level: colour.white_level as f32,
        },
        ColourSpaceName::Rgb => ColourSpace::Rgb,
    };
    let quantizer = QuantizerConfig {
        space,
        low_mid: colour.low_mid as f32,
        mid_high: colour.mid_high as f32,
        hysteresis: colour.hysteresis as f32,
    };
    (sampler, quantizer)
}

impl ColourSettings {
    /// The settings of the `[colour]` configuration section over `map`, checked again by the
    /// colour crate (the error names the field).
    pub fn from_config(map: SceneMap, colour: &ColourConfig) -> Result<Self, ColourThreadError> {
        let (sampler, quantizer) = colour_levels(colour);
        let settings = ColourSettings {
            map,
            sampler,
            quantizer,
            pattern: PatternConfig {
                frequency_hz: colour.frequency_hz,
                duty: colour.duty,
            },
            ticks_per_period: TICKS_PER_PERIOD,
        };
        settings.quantizer.validate().map_err(config_error)?;
        Pattern::new(settings.pattern).map_err(config_error)?;
        Ok(settings)
    }
}

/// The twin's colour source for `videtd --sim`: the demo image over the explored area, sampled,
/// quantized and rendered as `colour` says.
pub fn demo_colour(
    guides_m: &[[f64; 2]; 3],
    wall_z_m: f64,
    colour: &ColourConfig,
) -> Result<ColourSource, ColourThreadError> {
    let frame = videt_colour::training::decode_rgb(
        DEMO_IMAGE_PNG.to_vec(),
        std::path::Path::new("assets/colour-demo/cones-left-crop.png"),
    )
    .map_err(config_error)?;
    let map =
        demo_scene_map(guides_m, wall_z_m, [frame.width, frame.height]).map_err(config_error)?;
    Ok(ColourSource {
        frame,
        settings: ColourSettings::from_config(map, colour)?,
        outputs: ColourOutputs::Recording,
        camera_frames: None,
    })
}

/// The colour thread's body: runs until `handles.inputs.request_shutdown()`, then leaves every
/// output off and returns the loop's period statistics and the device.
pub fn run_colour<V, C>(
    vibrotactors: V,
    clock: C,
    settings: &ColourSettings,
    handles: &ColourHandles,
    mut thimble: SnapshotReader<ThimbleState>,
    mut frames: SnapshotReader<RgbFrame>,
) -> Result<(PeriodJitter, V), ColourThreadError>
where
    V: Vibrotactors,
    C: Clock,
{
    let pattern = Pattern::new(settings.pattern).map_err(config_error)?;
    let mut reader =
        ColourReader::new(settings.sampler, settings.quantizer).map_err(config_error)?;
    let mut vibration = VibrationLoop::new(
        vibrotactors,
        clock,
        pattern,
        settings.ticks_per_period,
        Arc::clone(&handles.inputs),
    )
    .map_err(config_error)?;
    let inputs = &handles.inputs;
    let mut tick = 0u64;
    loop {
        if tick.is_multiple_of(TICKS_PER_READING) {
            let state = thimble.latest();
            let (version, [x, y, _]) = (state.version, state.value.position_m);
            let frame = &frames.latest().value;
            let reading = if version == 0 {
                None // the control loop has not published a position yet
            } else {
                reader.read_workspace(frame, &settings.map, x, y).ok()
            };
            inputs.set_levels(reading.map(|r| r.levels));
            handles.status.set(reading.map(|r| r.rgb));
        }
        tick += 1;
        if !vibration.step()? {
            break;
        }
    }
    let jitter = vibration.jitter().clone();
    let (vibrotactors, _clock) = vibration.into_parts();
    Ok((jitter, vibrotactors))
}

/// The colour thread's result: its period statistics and the vibrotactors handed back.
pub type ColourJoin<V> = JoinHandle<Result<(PeriodJitter, V), ColourThreadError>>;

/// Start the colour thread (named `videt-colour`); `handles.inputs.request_shutdown()` stops
/// it. With `fifo_priority` the thread asks for SCHED_FIFO at that priority (below the control
/// thread's); if refused it warns and runs with normal scheduling.
pub fn spawn_colour_thread<V, C>(
    vibrotactors: V,
    clock: C,
    settings: ColourSettings,
    thimble: SnapshotReader<ThimbleState>,
    frames: SnapshotReader<RgbFrame>,
    fifo_priority: Option<u8>,
) -> std::io::Result<(ColourHandles, ColourJoin<V>)>
where
    V: Vibrotactors + Send + 'static,
    C: Clock + Send + 'static,
{
    let handles = ColourHandles {
        inputs: Arc::new(VibrationInputs::new()),
        status: Arc::new(ColourStatus::default()),
    };
    let thread_handles = handles.clone();
    let join = std::thread::Builder::new()
        .name("videt-colour".into())
        .spawn(move || {
            if let Some(priority) = fifo_priority {
                if let Err(e) = videt_runtime::rt::set_fifo(priority) {
                    warn!(
                        "colour thread stays SCHED_OTHER: SCHED_FIFO {priority} refused ({e}); vibration timing will be worse"
                    );
                }
            }
            videt_runtime::rt::prefault_stack(64 * 1024);
            run_colour(
                vibrotactors,
                clock,
                &settings,
                &thread_handles,
                thimble,
                frames,
            )
        })?;
    Ok((handles, join))
}

/// The vibrotactors the service drives: the twin's recording ones or the device's GPIO lines.
pub enum ServiceVibrotactors {
    /// The twin's.
    Recording(RecordingVibrotactors<SystemClock>),
    /// The device's (boxed: they are several times the twin's size).
    #[cfg(target_os = "linux")]
    Gpio(Box<videt_drivers::gpio::vibro::VibrotactorOutputs<videt_drivers::gpio::linux::CdevPin>>),
}

impl ServiceVibrotactors {
    /// Open the vibrotactors `outputs` names.
    pub fn open(outputs: &ColourOutputs) -> Result<ServiceVibrotactors, ColourThreadError> {
        match outputs {
            ColourOutputs::Recording => Ok(ServiceVibrotactors::Recording(
                RecordingVibrotactors::new(SystemClock, TWIN_EDGE_CAPACITY),
            )),
            #[cfg(target_os = "linux")]
            ColourOutputs::Gpio { chip, lines } => {
                videt_drivers::gpio::linux::vibrotactors(chip, *lines)
                    .map(|v| ServiceVibrotactors::Gpio(Box::new(v)))
                    .map_err(|e| {
                        ColourThreadError::Config(format!(
                            "vibrotactors: {e} (sensors.gpio_chip, sensors.vibrotactor_lines)"
                        ))
                    })
            }
            #[cfg(not(target_os = "linux"))]
            ColourOutputs::Gpio { .. } => Err(ColourThreadError::Config(
                "GPIO vibrotactors need Linux".into(),
            )),
        }
    }
}

impl videt_hal::ErrorType for ServiceVibrotactors {
    type Error = videt_hal::ErrorKind;
}

impl Vibrotactors for ServiceVibrotactors {
    fn set_outputs(&mut self, on: &[bool; 3]) -> Result<(), videt_hal::ErrorKind> {
        match self {
            ServiceVibrotactors::Recording(v) => v.set_outputs(on),
            #[cfg(target_os = "linux")]
            ServiceVibrotactors::Gpio(v) => {
                v.set_outputs(on).map_err(|e| videt_hal::Error::kind(&e))
            }
        }
    }
}

/// The colour thread as the service runs it: on the twin's recording vibrotactors or the
/// device's GPIO ones, on the system clock.
pub struct ColourRuntime {
    handles: ColourHandles,
    join: ColourJoin<ServiceVibrotactors>,
    /// Where newer frames are published, unless a camera publishes them
    /// ([`ColourSource::camera_frames`]).
    pub frames: Option<SnapshotWriter<RgbFrame>>,
}

impl ColourRuntime {
    /// Start the colour thread for `source`, reading thimble states from `thimble`. Fails when
    /// the vibrotactors cannot be opened (the message names the lines and their fields).
    pub fn start(
        source: &ColourSource,
        thimble: SnapshotReader<ThimbleState>,
        fifo_priority: Option<u8>,
    ) -> Result<ColourRuntime, ColourThreadError> {
        let (frames, frame_reader) = match source.camera_frames.as_ref().and_then(|f| f.take()) {
            Some(reader) => (None, reader),
            None => {
                let (writer, reader) = snapshot_channel(source.frame.clone());
                (Some(writer), reader)
            }
        };
        let vibrotactors = ServiceVibrotactors::open(&source.outputs)?;
        let (handles, join) = spawn_colour_thread(
            vibrotactors,
            SystemClock,
            source.settings,
            thimble,
            frame_reader,
            fifo_priority,
        )
        .map_err(|e| ColourThreadError::Config(format!("cannot start the colour thread: {e}")))?;
        Ok(ColourRuntime {
            handles,
            join,
            frames,
        })
    }

    /// The shared state (levels, status).
    pub fn handles(&self) -> &ColourHandles {
        &self.handles
    }

    /// Called by the supervisor with the latest control record: render only while the control
    /// loop runs in its normal state and the service is not stopping.
    pub fn supervise(&self, record: &CycleRecord, stopping: bool) {
        let rendering = record.cycle > 0 && record.safety == SafetyState::Normal && !stopping;
        self.handles.inputs.set_active(rendering);
    }

    /// The status-line text.
    pub fn status_text(&self) -> String {
        self.handles.status_text()
    }

    /// Switch everything off, stop the thread and log its timing.
    pub fn finish(self) {
        self.handles.inputs.set_active(false);
        self.handles.inputs.request_shutdown();
        let stopped = self.join.join().map(|r| {
            r.map(|(jitter, vibrotactors)| {
                let recorded = match vibrotactors {
                    ServiceVibrotactors::Recording(v) => Some((v.edges().len(), v.dropped_edges())),
                    #[cfg(target_os = "linux")]
                    ServiceVibrotactors::Gpio(_) => None,
                };
                (jitter, recorded)
            })
        });
        match stopped {
            Ok(Ok((jitter, recorded))) => info!(
                ticks = jitter.count() + 1,
                p99_period_deviation_us = jitter
                    .p99_deviation_ns()
                    .map_or(f64::NAN, |v| v as f64 * 1e-3),
                max_lateness_us = jitter.max_lateness_ns() as f64 * 1e-3,
                missed_ticks = jitter.missed_ticks(),
                edges = recorded.map(|r| r.0),
                dropped_edges = recorded.map(|r| r.1),
                "colour thread stopped: vibrotactors off"
            ),
            Ok(Err(e)) => error!("colour thread: {e}"),
            Err(_) => error!("the colour thread panicked"),
        }
    }
}

/// Whether `[colour]` asks for the colour under the finger; says so when it does not.
pub fn colour_enabled(config: &videt_config::Config) -> bool {
    if !config.colour.enabled {
        tracing::info!("colour rendering off (colour.enabled = false)");
    }
    config.colour.enabled
}
