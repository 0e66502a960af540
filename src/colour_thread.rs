//! The colour thread of `videtd`: the colour under the thimble rendered as vibration
//! (paper §6.1).
//!
//! One thread runs the [`VibrationLoop`] at its tick (1.5 kHz by default, absolute-time sleeps)
//! and, every few ticks, reads the latest thimble position (published by the control thread
//! through a wait-free snapshot) and the latest colour frame, samples the colour under the
//! thimble through the [`SceneMap`], quantizes it with hysteresis and hands the level triple to
//! the loop. The vibrotactors are silent whenever the control loop is not in its normal state,
//! the finger is outside the image, or no frame has arrived; on shutdown they are switched off.
//! Nothing on this thread allocates after start-up.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use videt_colour::level::triple_letters;
use videt_colour::vibration_loop::VibrationError;
use videt_colour::{
    ColourReader, LevelTriple, Pattern, PatternConfig, PeriodJitter, QuantizerConfig,
    SamplerConfig, VibrationInputs, VibrationLoop,
};
use videt_control::safety::SafetyState;
use videt_control::SceneMap;
use videt_hal::{Clock, RgbFrame, Vibrotactors};

use crate::control_loop::{CycleObserver, WindowStats};
use crate::cycle::CycleRecord;

/// The demonstration image `videtd --sim` renders: a crop of the Middlebury "cones" left image
/// (attribution in `assets/colour-demo/ATTRIBUTION.md`).
pub const DEMO_IMAGE_PNG: &[u8] = include_bytes!("../assets/colour-demo/cones-left-crop.png");

/// Vibration ticks between two colour readings (1.5 kHz / 25 = 60 readings per second).
pub const TICKS_PER_READING: u64 = 25;

/// What the colour thread needs of the control thread's state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ThimbleSnapshot {
    /// Thimble position, metres (device frame).
    pub position_m: [f64; 3],
    /// The control loop is in its normal state (not in a safe state) and has published.
    pub rendering: bool,
}

/// Publishes the thimble snapshot from the control thread (wait-free, no allocation).
pub struct ThimblePublisher {
    input: triple_buffer::Input<ThimbleSnapshot>,
}

/// Reads the latest thimble snapshot.
pub struct ThimbleReader {
    output: triple_buffer::Output<ThimbleSnapshot>,
}

/// A connected thimble publisher/reader pair.
pub fn thimble_channel() -> (ThimblePublisher, ThimbleReader) {
    let (input, output) = triple_buffer::triple_buffer(&ThimbleSnapshot::default());
    (ThimblePublisher { input }, ThimbleReader { output })
}

impl CycleObserver for ThimblePublisher {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        self.input.write(ThimbleSnapshot {
            position_m: record.position_m,
            rendering: matches!(record.safety, SafetyState::Normal),
        });
    }
}

impl ThimbleReader {
    /// The latest snapshot.
    pub fn latest(&mut self) -> ThimbleSnapshot {
        *self.output.read()
    }
}

/// Two observers of the control loop, both called every period.
impl<A: CycleObserver, B: CycleObserver> CycleObserver for (A, B) {
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats) {
        self.0.observe(record, window);
        self.1.observe(record, window);
    }
}

/// Publishes colour frames to the colour thread. The frame buffers are reused: write into
/// [`ColourFramePublisher::frame_mut`], then [`ColourFramePublisher::publish`].
pub struct ColourFramePublisher {
    input: triple_buffer::Input<RgbFrame>,
}

/// The colour thread's end of the frame channel.
pub struct ColourFrameReader {
    output: triple_buffer::Output<RgbFrame>,
}

/// A connected frame publisher/reader pair; the three buffers start as copies of `initial`
/// (allocate them at the camera's size so publishing never reallocates).
pub fn colour_frame_channel(initial: &RgbFrame) -> (ColourFramePublisher, ColourFrameReader) {
    let (input, output) = triple_buffer::triple_buffer(initial);
    (ColourFramePublisher { input }, ColourFrameReader { output })
}

impl ColourFramePublisher {
    /// The back buffer to fill.
    pub fn frame_mut(&mut self) -> &mut RgbFrame {
        self.input.input_buffer_mut()
    }
    /// Make the back buffer the latest frame.
    pub fn publish(&mut self) {
        self.input.publish();
    }
}

/// What the status line shows: the current levels and the colour they came from.
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
    /// The colour under the thimble for the status line.
    pub status: Arc<ColourStatus>,
}

impl ColourHandles {
    /// `colour HLL rgb(230, 39, 59)`, `colour quiet (off-image)`, or `colour quiet (safe state)`.
    pub fn status_text(&self) -> String {
        let levels: Option<LevelTriple> = self.inputs.levels();
        match (self.inputs.is_active(), levels, self.status.rgb()) {
            (true, Some(l), Some([r, g, b])) => {
                let [a, b2, c] = triple_letters(l);
                format!("colour {a}{b2}{c} rgb({r:3}, {g:3}, {b:3})")
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

/// The colour thread's body: runs until `inputs.request_shutdown()`, then leaves every output
/// off and returns the loop's period statistics.
pub fn run_colour<V, C>(
    vibrotactors: V,
    clock: C,
    settings: &ColourSettings,
    handles: &ColourHandles,
    mut thimble: ThimbleReader,
    mut frames: ColourFrameReader,
) -> Result<(PeriodJitter, V), ColourThreadError>
where
    V: Vibrotactors,
    C: Clock,
{
    let pattern = Pattern::new(settings.pattern)?;
    let mut reader = ColourReader::new(settings.sampler, settings.quantizer)?;
    let mut vibration = VibrationLoop::new(
        vibrotactors,
        clock,
        pattern,
        settings.ticks_per_period,
        Arc::clone(&handles.inputs),
    )?;
    let inputs = &handles.inputs;
    let mut tick = 0u64;
    loop {
        if tick % TICKS_PER_READING == 0 {
            let snapshot = thimble.latest();
            let frame = frames.output.read();
            let [x, y, _] = snapshot.position_m;
            match reader.read_workspace(frame, &settings.map, x, y) {
                Ok(reading) => {
                    inputs.set_levels(Some(reading.levels));
                    handles.status.set(Some(reading.rgb));
                }
                Err(_) => {
                    inputs.set_levels(None);
                    handles.status.set(None);
                }
            }
            inputs.set_active(snapshot.rendering);
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

/// Why the colour thread stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ColourThreadError {
    /// A configuration was rejected.
    #[error("colour settings: {0}")]
    Config(String),
    /// A vibrotactor write failed (outputs were switched off).
    #[error(transparent)]
    Output(#[from] VibrationError),
}

impl From<videt_colour::pattern::PatternConfigError> for ColourThreadError {
    fn from(e: videt_colour::pattern::PatternConfigError) -> Self {
        ColourThreadError::Config(e.to_string())
    }
}
impl From<videt_colour::reader::ReaderConfigError> for ColourThreadError {
    fn from(e: videt_colour::reader::ReaderConfigError) -> Self {
        ColourThreadError::Config(e.to_string())
    }
}
impl From<videt_colour::vibration_loop::LoopConfigError> for ColourThreadError {
    fn from(e: videt_colour::vibration_loop::LoopConfigError) -> Self {
        ColourThreadError::Config(e.to_string())
    }
}

/// The colour thread's result: its period statistics and the vibrotactors handed back.
pub type ColourJoin<V> = JoinHandle<Result<(PeriodJitter, V), ColourThreadError>>;

/// Start the colour thread (named `videt-colour`); set `handles.inputs.request_shutdown()` to
/// stop it. With `fifo_priority` the thread asks for SCHED_FIFO at that priority (below the
/// control thread's); if refused it warns and runs with normal scheduling.
pub fn spawn_colour_thread<V, C>(
    vibrotactors: V,
    clock: C,
    settings: ColourSettings,
    thimble: ThimbleReader,
    frames: ColourFrameReader,
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
                if let Err(e) = crate::rt::set_fifo(priority) {
                    tracing::warn!(
                        "colour thread stays SCHED_OTHER: SCHED_FIFO {priority} refused ({e}); vibration timing will be worse"
                    );
                }
            }
            crate::rt::prefault_stack(64 * 1024);
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

/// The twin's colour set-up for `videtd --sim`: the demo image, its scene map over the rig, and
/// default sampling, quantization and pattern.
pub fn demo_colour(
    guides_m: &[[f64; 2]; 3],
    wall_z_m: f64,
) -> Result<(RgbFrame, ColourSettings), ColourThreadError> {
    let frame = videt_colour::training::decode_rgb(
        DEMO_IMAGE_PNG.to_vec(),
        std::path::Path::new("assets/colour-demo/cones-left-crop.png"),
    )
    .map_err(|e| ColourThreadError::Config(e.to_string()))?;
    let map = demo_scene_map(guides_m, wall_z_m, [frame.width, frame.height])
        .map_err(|e| ColourThreadError::Config(e.to_string()))?;
    let settings = ColourSettings {
        map,
        sampler: SamplerConfig::default(),
        quantizer: QuantizerConfig::default(),
        pattern: PatternConfig::default(),
        ticks_per_period: 20,
    };
    Ok((frame, settings))
}
