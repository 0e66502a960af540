//! The live view: the session's topics served over the Foxglove WebSocket protocol while the
//! device runs.
//!
//! A thread of its own samples the control loop's status (a triple buffer the control thread
//! writes every period: wait-free, no allocation, nothing formatted on the control thread) at
//! `live.rate_hz`, and logs what changed through [`SessionTopics`] (the Foxglove SDK's
//! well-known schemas) to the [`WsServer`] of this crate, which speaks the Foxglove WebSocket
//! protocol as `foxglove.websocket.v1` (the name Foxglove, Lichtblick and PlotJuggler connect
//! with; the SDK's own server speaks only `foxglove.sdk.v1`). Clients only subscribe: no client
//! publishing, no services, no parameters. Each client has a bounded queue; a slow or stalled
//! client loses its oldest messages and never delays the sampling thread, which in turn never
//! delays the control thread.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use foxglove::schemas::RawImage;
use foxglove::{Channel, Context};
use videt_config::Config;
use videt_runtime::status::StatusReader;
use videt_runtime::telemetry::{
    CalibrationInForce, FeedRecording, RecordedSurface, SessionLogHealth,
};

use crate::topics::{timestamp, SceneSetup, SessionTopics};
use crate::ws_server::WsServer;

/// The topic of the rectified left camera image (`foxglove.RawImage`, `mono8`), when cameras
/// run.
pub const IMAGE_TOPIC: &str = "/camera/left/rectified";

/// How often the state that changes seldom (the surface, the safety state) is sent again
/// although it has not changed, so that a client that subscribes later (or lost the message)
/// sees it.
const REPEAT: Duration = Duration::from_secs(1);

/// How the live view is served.
#[derive(Debug, Clone, PartialEq)]
pub struct LiveSettings {
    /// Host or address to listen on.
    pub host: String,
    /// Port (0: any free port; [`LiveView::port`] says which).
    pub port: u16,
    /// Samples per second.
    pub rate_hz: f64,
    /// Messages queued per client before the oldest are dropped.
    pub client_backlog: usize,
    /// The control thread's CPU, which the view's threads keep off (`None`: anywhere).
    pub avoid_cpu: Option<usize>,
}

impl LiveSettings {
    /// The settings of a validated configuration's `[live]` section; the view keeps off
    /// `realtime.control_cpu`.
    pub fn from_config(config: &Config) -> Result<LiveSettings, String> {
        let live = &config.live;
        let (host, port) = live.host_port().map_err(|e| e.to_string())?;
        Ok(LiveSettings {
            host,
            port,
            rate_hz: live.rate_hz,
            client_backlog: live.client_backlog as usize,
            avoid_cpu: usize::try_from(config.realtime.control_cpu).ok(),
        })
    }
}

/// The newest rectified left camera image, shared by the vision thread (which copies each
/// frame into it) and the live view (which sends it). The vision thread only ever tries the
/// lock: a frame is skipped rather than waited for.
#[derive(Default)]
pub struct ImageSlot {
    newest: Mutex<Option<GreyFrame>>,
}

/// A grey image and when it was captured.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GreyFrame {
    /// Capture time on the service's monotonic clock, nanoseconds.
    pub captured_ns: u64,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Row-major pixels, one byte each.
    pub pixels: Vec<u8>,
    /// Frames put into the slot so far (the live view sends each one once).
    pub sequence: u64,
}

impl ImageSlot {
    /// Copy a frame into the slot (reusing its buffer); skipped if the live view is reading
    /// the previous one.
    pub fn offer(&self, captured_ns: u64, width: u32, height: u32, pixels: &[u8]) {
        if let Ok(mut slot) = self.newest.try_lock() {
            let frame = slot.get_or_insert_with(GreyFrame::default);
            frame.captured_ns = captured_ns;
            frame.width = width;
            frame.height = height;
            frame.pixels.clear();
            frame.pixels.extend_from_slice(pixels);
            frame.sequence += 1;
        }
    }

    /// Run `f` on the newest frame if it is newer than `after` (its sequence number).
    fn newest_after<R>(&self, after: u64, f: impl FnOnce(&GreyFrame) -> R) -> Option<R> {
        let slot = self.newest.lock().unwrap_or_else(PoisonError::into_inner);
        slot.as_ref().filter(|frame| frame.sequence > after).map(f)
    }
}

/// Where the live view reads from.
pub struct LiveSources {
    /// The control loop's status, written by the control thread every period.
    pub status: StatusReader,
    /// The surfaces: the first one and the tap the vision thread publishes through.
    pub surfaces: FeedRecording,
    /// The cameras' rectified left image, when cameras run.
    pub image: Option<Arc<ImageSlot>>,
    /// Calibrations that replace the one the view started with (a re-initialization through
    /// the service), pushed by the control thread (wait-free).
    pub calibrations: Option<rtrb::Consumer<CalibrationInForce>>,
    /// The configuration (the scene's device, guides and tension range).
    pub config: Config,
    /// The session log's writes (`None`: no log): a failing disk shows on `/safety`.
    pub session_log: Option<SessionLogHealth>,
}

/// A wait-free channel of calibrations for [`LiveSources::calibrations`]: the control thread
/// pushes each new one (a full channel drops it; a few fit).
pub fn calibration_channel() -> (
    rtrb::Producer<CalibrationInForce>,
    rtrb::Consumer<CalibrationInForce>,
) {
    rtrb::RingBuffer::new(4)
}

/// What the live view did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LiveStats {
    /// Samples of the control loop sent.
    pub samples: u64,
    /// Surfaces sent (new versions and repeats).
    pub surfaces: u64,
    /// Camera images sent.
    pub images: u64,
    /// How long the sampling thread ran, seconds.
    pub wall_s: f64,
    /// CPU time of the sampling thread, seconds.
    pub cpu_s: f64,
    /// Clients served.
    pub connections: u64,
    /// Messages dropped for clients that did not keep up.
    pub dropped: u64,
}

impl LiveStats {
    /// CPU share of one core taken by the sampling thread.
    pub fn cpu_share(&self) -> f64 {
        if self.wall_s > 0.0 {
            self.cpu_s / self.wall_s
        } else {
            0.0
        }
    }
}

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The server could not start (its address in use, not an address of this machine, ...).
    #[error("live view: {0}")]
    Serve(#[from] crate::ws_server::ServeError),
    /// The sampling thread could not be started.
    #[error("live view: cannot start its thread: {0}")]
    Thread(std::io::Error),
}

/// A running live view: the server and the sampling thread.
pub struct LiveView {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<LiveStats>>,
    server: Option<WsServer>,
    /// The topics' context: dropping it would close the channels.
    _context: Arc<Context>,
    port: u16,
}

impl LiveView {
    /// Start serving `setup`'s scene from `sources`.
    pub fn start(
        settings: &LiveSettings,
        setup: SceneSetup,
        sources: LiveSources,
    ) -> Result<LiveView, LiveError> {
        let context = Context::new();
        let topics = SessionTopics::new(&context, setup);
        let image_channel = sources
            .image
            .is_some()
            .then(|| context.channel_builder(IMAGE_TOPIC).build::<RawImage>());
        let server = WsServer::start(
            &context,
            &settings.host,
            settings.port,
            settings.client_backlog,
            settings.avoid_cpu,
        )?;
        let port = server.address().port();
        let stop = Arc::new(AtomicBool::new(false));
        let thread_stop = Arc::clone(&stop);
        let period = Duration::from_secs_f64(1.0 / settings.rate_hz.clamp(0.1, 1000.0));
        let avoid_cpu = settings.avoid_cpu;
        let thread = std::thread::Builder::new()
            .name("videt-live".into())
            .spawn(move || {
                if let Some(cpu) = avoid_cpu {
                    videt_runtime::rt::keep_off_cpu(cpu);
                }
                let mut sources = sources;
                let initial = sources.surfaces.initial.take().map(Arc::new);
                Sampler {
                    topics,
                    image_channel,
                    stats: LiveStats::default(),
                    last_cycle: None,
                    last_surface: None,
                    last_image: 0,
                    last_state_repeat: Instant::now(),
                    initial,
                    sources,
                }
                .run(&thread_stop, period)
            })
            .map_err(LiveError::Thread)?;
        Ok(LiveView {
            stop,
            thread: Some(thread),
            server: Some(server),
            _context: context,
            port,
        })
    }

    /// The port the server listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// Clients connected now.
    pub fn clients(&self) -> usize {
        self.server.as_ref().map_or(0, WsServer::clients)
    }

    /// Stop sampling, close the clients' connections and the server; what the view did.
    pub fn stop(mut self) -> LiveStats {
        self.shut_down()
    }

    fn shut_down(&mut self) -> LiveStats {
        self.stop.store(true, Ordering::Release);
        let mut stats = self
            .thread
            .take()
            .and_then(|t| t.join().ok())
            .unwrap_or_default();
        if let Some(server) = self.server.take() {
            stats.dropped = server.dropped();
            stats.connections = server.connections();
            server.stop();
        }
        stats
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if self.thread.is_some() {
            self.shut_down();
        }
    }
}

/// The sampling thread's state.
struct Sampler {
    topics: SessionTopics,
    image_channel: Option<Channel<RawImage>>,
    sources: LiveSources,
    stats: LiveStats,
    last_cycle: Option<u64>,
    /// The version last sent and when.
    last_surface: Option<(u64, Instant)>,
    last_image: u64,
    last_state_repeat: Instant,
    /// The feed's first surface, shared.
    initial: Option<Arc<RecordedSurface>>,
}

impl Sampler {
    fn run(mut self, stop: &AtomicBool, period: Duration) -> LiveStats {
        let started = Instant::now();
        let cpu_at_start = videt_runtime::rt::thread_cpu_time().as_secs_f64();
        let mut next = Instant::now();
        while !stop.load(Ordering::Acquire) {
            self.sample();
            next += period;
            let now = Instant::now();
            if next > now {
                std::thread::sleep(next - now);
            } else {
                // Late (a loaded machine): skip the missed samples rather than catch up.
                next = now;
            }
        }
        self.stats.wall_s = started.elapsed().as_secs_f64();
        self.stats.cpu_s = videt_runtime::rt::thread_cpu_time().as_secs_f64() - cpu_at_start;
        self.stats
    }

    /// One sample: the newest period if the loop has run since the last one, the surface if
    /// it changed (or is due again), the camera image if a new one came.
    fn sample(&mut self) {
        if let Some(calibrations) = self.sources.calibrations.as_mut() {
            while let Ok(c) = calibrations.pop() {
                let setup = SceneSetup::new(&self.sources.config, Some(&c));
                self.topics.set_guides(&setup);
            }
        }
        if let Some(log) = &self.sources.session_log {
            self.topics.set_session_log_error(log.failure());
        }
        let snapshot = self.sources.status.latest();
        let record = snapshot.record;
        let running = record.cycle > 0;
        if running && self.last_cycle != Some(record.cycle) {
            self.last_cycle = Some(record.cycle);
            if self.last_state_repeat.elapsed() >= REPEAT {
                self.topics.forget_logged_safety();
                self.last_state_repeat = Instant::now();
            }
            self.topics.log_period(&record);
            self.stats.samples += 1;
        }
        let time_ns = record.time.as_nanos();
        // The newest version published, else the feed's first surface (version 0).
        let newest = self
            .sources
            .surfaces
            .tap
            .as_ref()
            .and_then(|tap| tap.newest())
            .or_else(|| self.initial.clone().map(|s| (0, s)));
        if let Some((version, surface)) = newest {
            let due = match self.last_surface {
                Some((v, at)) => v != version || at.elapsed() >= REPEAT,
                None => true,
            };
            if due {
                self.send_surface(version, &surface, time_ns);
            }
        }
        if let (Some(slot), Some(channel)) = (&self.sources.image, &self.image_channel) {
            let sent = slot.newest_after(self.last_image, |frame| {
                channel.log_with_time(&raw_image(frame), frame.captured_ns);
                frame.sequence
            });
            if let Some(sequence) = sent {
                self.last_image = sequence;
                self.stats.images += 1;
            }
        }
    }

    fn send_surface(&mut self, version: u64, surface: &RecordedSurface, time_ns: u64) {
        self.topics.log_surface(version, surface, time_ns);
        self.last_surface = Some((version, Instant::now()));
        self.stats.surfaces += 1;
    }
}

/// A grey frame as a `foxglove.RawImage` (`mono8`) in the left camera's frame.
fn raw_image(frame: &GreyFrame) -> RawImage {
    RawImage {
        timestamp: Some(timestamp(frame.captured_ns)),
        frame_id: "camera_left".into(),
        width: frame.width,
        height: frame.height,
        encoding: "mono8".into(),
        step: frame.width,
        data: frame.pixels.clone().into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_runtime::status::status_channel;

    #[test]
    fn a_re_initialization_moves_the_guides_the_view_draws() {
        let config = Config::default();
        let context = Context::new();
        let (_publisher, status) = status_channel();
        let (mut calibrations, calibration_rx) = calibration_channel();
        let mut sampler = Sampler {
            topics: SessionTopics::new(&context, SceneSetup::new(&config, None)),
            image_channel: None,
            sources: LiveSources {
                status,
                surfaces: FeedRecording::default(),
                image: None,
                calibrations: Some(calibration_rx),
                config: config.clone(),
                session_log: None,
            },
            stats: LiveStats::default(),
            last_cycle: None,
            last_surface: None,
            last_image: 0,
            last_state_repeat: Instant::now(),
            initial: None,
        };
        let configured = sampler.topics.setup().guides_m.clone();
        sampler.sample();
        assert_eq!(sampler.topics.setup().guides_m, configured);
        let moved = [[0.01, 0.0, 0.0], [0.41, 0.01, 0.0], [0.2, 0.36, 0.0]];
        calibrations
            .push(CalibrationInForce {
                guides_m: moved,
                length_at_zero_m: [0.3; 3],
                calibrated: true,
            })
            .unwrap();
        sampler.sample();
        assert_eq!(sampler.topics.setup().guides_m, moved.to_vec());
    }

    #[test]
    fn the_image_slot_hands_each_frame_over_once() {
        let slot = ImageSlot::default();
        assert_eq!(slot.newest_after(0, |f| f.sequence), None);
        slot.offer(5, 2, 1, &[7, 9]);
        let frame = slot.newest_after(0, |f| f.clone()).unwrap();
        assert_eq!(
            (frame.width, frame.height, frame.pixels.as_slice()),
            (2, 1, &[7, 9][..])
        );
        assert_eq!(frame.captured_ns, 5);
        assert_eq!(slot.newest_after(frame.sequence, |f| f.sequence), None);
        let image = raw_image(&frame);
        assert_eq!((image.encoding.as_str(), image.step), ("mono8", 2));
    }
}
