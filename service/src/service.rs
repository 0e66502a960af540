//! The service: control thread, telemetry writer, control socket and the supervisor (systemd
//! notify and watchdog, status lines, logging of safety transitions). Generic over the hardware
//! and the surface feed, so the device and the twin run the same service code.

use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use sd_notify::NotifyState;
use tracing::{error, info, warn};
use videt_control::safety::SafetyState;
use videt_rt_config::Config;

use crate::init::remote::procedure_channel;
use crate::service_hardware::ServiceHardware;
use crate::socket::{self, ServerSettings, ServerShared, StatusReport};
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopEnd, LoopReport,
    LoopSettings, LoopStats, SERVICE_PANICKED,
};
use videt_runtime::cycle::ControlCycle;
use videt_runtime::rt;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::snapshot::SurfaceFeed;
use videt_runtime::status::{status_channel, StatusPublisher, StatusSnapshot};
use videt_runtime::telemetry::{
    self, CalibrationInForce, EndReason, LogHeader, TelemetryProducer, WriterEvent,
};

/// Exit code after a panic in any thread.
pub const EXIT_PANIC: u8 = 70;

/// How the service runs.
#[derive(Debug, Clone)]
pub struct ServiceOptions {
    /// The validated configuration.
    pub config: Config,
    /// Stop cleanly after this many seconds.
    pub duration_s: Option<f64>,
    /// Control socket path (`None`: no socket).
    pub socket_path: Option<PathBuf>,
    /// Directory for the session log (`None`: no telemetry).
    pub telemetry_dir: Option<PathBuf>,
    /// Print one status line per second on stdout.
    pub status_lines: bool,
    /// Render the colour under the thimble on the vibrotactors (`None`: no colour thread).
    pub colour: Option<crate::colour_thread::ColourSource>,
    /// The calibration file auto-initialization through the control socket writes (`None`: the
    /// service runs no procedures).
    pub calibration_path: Option<PathBuf>,
    /// What runs (the scene, the device or the twin), for the session log.
    pub what: String,
    /// Serve the live view (`None`: off).
    pub live: Option<videt_viewers::live::LiveSettings>,
}

impl ServiceOptions {
    /// Options from the configuration alone.
    pub fn from_config(config: Config) -> ServiceOptions {
        let config_calibration = config.files.calibration.clone();
        let live = config
            .live
            .enabled
            .then(|| videt_viewers::live::LiveSettings::from_config(&config).ok())
            .flatten();
        let socket_path = Some(PathBuf::from(&config.socket.path));
        let telemetry_dir = config
            .telemetry
            .enabled
            .then(|| PathBuf::from(&config.telemetry.directory));
        ServiceOptions {
            config,
            duration_s: None,
            socket_path,
            telemetry_dir,
            status_lines: true,
            colour: None,
            calibration_path: Some(PathBuf::from(&config_calibration)),
            what: String::new(),
            live,
        }
    }
}

/// What a scene adds to the service: a second reader of the thimble state (a vision thread
/// that looks where the finger is) and a suffix for the status line.
#[derive(Default)]
pub struct ServiceExtras {
    /// Publishes the thimble state every period to a reader the caller keeps.
    pub thimble: Option<videt_runtime::thimble::ThimblePublisher>,
    /// Text appended to each status line (called on the supervisor thread, once a second).
    pub status_suffix: Option<Box<dyn Fn() -> String + Send>>,
    /// On the twin: while set, the scene's vision thread publishes nothing (a stalled camera,
    /// for `sim-fault vision-stall`).
    pub vision_stall: Option<Arc<AtomicBool>>,
    /// The hardware's account of why it went to its safe state: each call returns one cause
    /// not yet told (already formatted, off the control thread), `None` when there is none.
    /// The supervisor logs each beside the safe state it explains.
    pub fault_causes: Option<FaultCauses>,
    /// The drives' start-up report (identities, missing optional objects): logged once per
    /// configuration and carried in the status reply.
    pub drives_report: Option<videt_drivers::cia402::SharedStartupReport>,
    /// The cameras' rectified left image for the live view (a camera scene sets it).
    pub live_image: Option<Arc<videt_viewers::live::ImageSlot>>,
}

pub use videt_assembly::hardware::FaultCauses;

/// Log each hardware fault cause not yet told ([`ServiceExtras::fault_causes`]); the latest
/// one told, if any.
fn tell_fault_causes(fault_causes: &mut Option<FaultCauses>) -> Option<String> {
    let mut latest = None;
    if let Some(next_cause) = fault_causes.as_mut() {
        while let Some(cause) = next_cause() {
            warn!(%cause, "hardware fault");
            latest = Some(cause);
        }
    }
    latest
}

/// Install a panic hook that, besides printing, tells the control loop to go safe and stop.
pub fn install_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        SERVICE_PANICKED.store(true, Ordering::SeqCst);
        default(info);
    }));
}

/// The control thread's observers: status for the supervisor, telemetry for the log.
struct Observers {
    status: StatusPublisher,
    telemetry: Option<TelemetryProducer>,
    thimble: Option<videt_runtime::thimble::ThimblePublisher>,
    vision_thimble: Option<videt_runtime::thimble::ThimblePublisher>,
    /// The live view's copy of the status.
    live: Option<StatusPublisher>,
    /// The live view's calibrations (a re-initialization moves the guides it draws).
    live_calibrations: Option<rtrb::Producer<CalibrationInForce>>,
}

impl CycleObserver for Observers {
    fn observe(
        &mut self,
        record: &videt_runtime::cycle::CycleRecord,
        window: &videt_runtime::control_loop::WindowStats,
    ) {
        self.status.observe(record, window);
        if let Some(t) = self.telemetry.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.thimble.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.vision_thimble.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.live.as_mut() {
            t.observe(record, window);
        }
    }
}

/// Start the live view of `settings` on the status of a publisher it returns for the control
/// thread's observers. A view that cannot start (its port in use) is logged as an error and
/// the service runs without it: the device's rendering does not depend on being watched.
fn start_live_view<const N: usize, D, F>(
    settings: &videt_viewers::live::LiveSettings,
    config: &Config,
    cycle: &ControlCycle<N, D>,
    feed: &F,
    image: Option<Arc<videt_viewers::live::ImageSlot>>,
    session_log: Option<telemetry::SessionLogHealth>,
) -> (
    Option<StatusPublisher>,
    Option<rtrb::Producer<CalibrationInForce>>,
    Option<videt_viewers::live::LiveView>,
)
where
    D: RuntimeDevice<N>,
    F: SurfaceFeed,
{
    use videt_viewers::live::{LiveSources, LiveView};
    let (publisher, status) = status_channel();
    let setup =
        videt_viewers::topics::SceneSetup::new(config, Some(&CalibrationInForce::of(cycle)));
    let (calibration_tx, calibration_rx) = videt_viewers::live::calibration_channel();
    let sources = LiveSources {
        status,
        surfaces: feed.recording(),
        image,
        calibrations: Some(calibration_rx),
        config: config.clone(),
        session_log,
    };
    match LiveView::start(settings, setup, sources) {
        Ok(view) => {
            info!(
                "live view for Foxglove on ws://{}:{} ({} Hz, read-only)",
                settings.host,
                view.port(),
                settings.rate_hz
            );
            (Some(publisher), Some(calibration_tx), Some(view))
        }
        Err(e) => {
            error!("{e}; running without it");
            (None, None, None)
        }
    }
}

/// Run the service on `hw` with surfaces from `feed` until stopped; returns the exit code.
pub fn run_service<const N: usize, D, H, F>(
    hw: H,
    feed: F,
    cycle: ControlCycle<N, D>,
    options: &ServiceOptions,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    H: ServiceHardware<N>,
    F: SurfaceFeed + Send + 'static,
{
    run_service_with(hw, feed, cycle, options, ServiceExtras::default())
}

/// [`run_service`] with a scene's [`ServiceExtras`].
pub fn run_service_with<const N: usize, D, H, F>(
    mut hw: H,
    mut feed: F,
    mut cycle: ControlCycle<N, D>,
    options: &ServiceOptions,
    extras: ServiceExtras,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    H: ServiceHardware<N>,
    F: SurfaceFeed + Send + 'static,
{
    let ServiceExtras {
        thimble: vision_thimble,
        status_suffix,
        vision_stall,
        mut fault_causes,
        drives_report,
        live_image,
    } = extras;
    let mut drives_report = drives_report.map(crate::drive_report::DriveReportWatch::new);
    let extra_text = move || status_suffix.as_ref().map_or_else(String::new, |f| f());
    install_panic_hook();
    let config = &options.config;
    let _cpu_latency = u32::try_from(config.realtime.cpu_wakeup_latency_us)
        .ok()
        .and_then(|limit| match rt::hold_cpu_latency(limit) {
            Ok(guard) => Some(guard),
            Err(e) => {
                warn!("CPU wake-up latency not limited (/dev/cpu_dma_latency: {e}); idle states may delay wake-ups");
                None
            }
        });
    if config.realtime.lock_memory {
        if let Err(e) = rt::lock_memory() {
            warn!("memory not locked (mlockall: {e}); page faults may delay the control loop");
        }
    }
    let control_cpu = usize::try_from(config.realtime.control_cpu).ok();
    for w in rt::platform_warnings(control_cpu) {
        warn!("{w}");
    }
    let stop = Arc::new(AtomicBool::new(false));
    // The signal that raised `stop` (0: none), for the session log's end.
    let signalled = Arc::new(AtomicUsize::new(0));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        let registered =
            signal_hook::flag::register_usize(signal, Arc::clone(&signalled), signal as usize)
                .and_then(|_| signal_hook::flag::register(signal, Arc::clone(&stop)));
        if let Err(e) = registered {
            error!("cannot install the handler for signal {signal}: {e}");
            return ExitCode::FAILURE;
        }
    }
    // SIGHUP (a `systemctl reload`, a closed terminal) would end the process without ramping
    // the forces out: it is caught and said to do nothing.
    let hangup = Arc::new(AtomicBool::new(false));
    if let Err(e) = signal_hook::flag::register(signal_hook::consts::SIGHUP, Arc::clone(&hangup)) {
        error!("cannot install the handler for SIGHUP: {e}");
        return ExitCode::FAILURE;
    }

    // Telemetry.
    let mut telemetry_writer = None;
    let mut telemetry_producer = None;
    if let Some(dir) = &options.telemetry_dir {
        let start_unix_ns = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos() as u64)
            .unwrap_or(0);
        let path = dir.join(format!("videt-{}.vlog", start_unix_ns / 1_000_000_000));
        let started = std::fs::create_dir_all(dir).and_then(|()| {
            telemetry::start_session(
                &path,
                LogHeader {
                    rate_hz: config.control.rate_hz,
                    start_unix_ns,
                },
                telemetry::SessionRecording {
                    session: Some(telemetry::SessionInfo::new(&options.what, config.clone())),
                    surfaces: feed.recording(),
                    retention: Some(telemetry::retention::RetentionLimits::from_config(
                        &config.telemetry,
                    )),
                },
                config.telemetry.ring_records as usize,
            )
        });
        match started {
            Ok((producer, writer)) => {
                info!(log = %path.display(), "recording every control period");
                telemetry_producer = Some(producer);
                telemetry_writer = Some(writer);
            }
            Err(e) => warn!("telemetry disabled: cannot write {}: {e}", path.display()),
        }
    }

    // Control socket, and procedures run on this hardware for its clients.
    let (command_tx, mut command_rx) = rtrb::RingBuffer::new(64);
    let (procedure_port, mut procedure_handle) = match &options.calibration_path {
        Some(path) if options.socket_path.is_some() && hw.runs_procedures() => {
            let (port, handle) = procedure_channel(config.clone(), path.clone(), hw.is_twin());
            (Some(port), Some(handle))
        }
        _ => (None, None),
    };
    let shared = Arc::new(ServerShared {
        wires: N,
        status: Mutex::new(StatusReport::from_snapshot(
            &StatusSnapshot {
                wires: N,
                device: D::KIND.name(),
                ..StatusSnapshot::default()
            },
            0,
        )),
        commands: Mutex::new(command_tx),
        procedures: procedure_port,
        sim_faults: hw
            .sim_faults()
            .map(|port| videt_assembly::sim_faults::SimFaultPort {
                vision_stall,
                ..port
            }),
    });
    let server = match &options.socket_path {
        Some(path) => {
            let settings = ServerSettings {
                path: path.clone(),
                max_request_bytes: config.socket.max_request_bytes as usize,
                client_timeout: Duration::from_millis(u64::from(config.socket.client_timeout_ms)),
                max_clients: 8,
            };
            match socket::serve(settings, Arc::clone(&shared)) {
                Ok(s) => {
                    info!(socket = %path.display(), "control socket ready");
                    Some(s)
                }
                Err(e @ socket::ServerError::InUse(_)) => {
                    error!("{e}");
                    return ExitCode::FAILURE;
                }
                Err(e) => {
                    warn!("no control socket: {e}");
                    None
                }
            }
        }
        None => None,
    };

    // Control thread.
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: options.duration_s.map(|d| (d * 1e9) as u64),
        max_consecutive_overruns: config.realtime.max_consecutive_overruns,
    };
    let (mut publisher, mut reader) = status_channel();
    publisher.set_device(D::KIND.name(), N);
    if let Ok(videt_runtime::tension_budget::TensionLoopPlan::Degraded { scale, .. }) =
        videt_runtime::tension_budget::plan(config)
    {
        publisher.set_tension_loop_degraded(Some(scale));
    }
    let priority = config.realtime.control_priority;
    let (thimble_publisher, thimble_reader) = videt_runtime::thimble::thimble_channel();
    let colour = options.colour.as_ref().and_then(|source| {
        let colour_priority = Some(priority.saturating_sub(10).max(1));
        crate::colour_thread::ColourRuntime::start(source, thimble_reader, colour_priority)
            .map_err(|e| warn!("colour rendering disabled: {e}"))
            .ok()
    });
    let thimble_publisher = colour.is_some().then_some(thimble_publisher);
    let (live_publisher, live_calibrations, live_view) = match &options.live {
        Some(settings) => start_live_view::<N, D, F>(
            settings,
            config,
            &cycle,
            &feed,
            live_image,
            telemetry_writer.as_ref().map(|w| w.health()),
        ),
        None => (None, None, None),
    };
    let thread_stop = Arc::clone(&stop);
    let thread_config = config.clone();
    let control = std::thread::Builder::new()
        .name("videt-control".into())
        .spawn(move || {
            let report = rt::setup_control_thread(priority, control_cpu);
            for w in &report.warnings {
                warn!("{w}");
            }
            start_hardware(&mut hw).map_err(|e| e.to_string())?;
            let mut telemetry_producer = telemetry_producer;
            if let Some(t) = telemetry_producer.as_mut() {
                t.calibration(cycle.cycle_count(), &CalibrationInForce::of(&cycle));
            }
            let mut observers = Observers {
                status: publisher,
                telemetry: telemetry_producer,
                thimble: thimble_publisher,
                vision_thimble,
                live: live_publisher,
                live_calibrations,
            };
            let mut stats = LoopStats::default();
            let mut loop_control = LoopControl {
                stop: &thread_stop,
                commands: Some(&mut command_rx),
            };
            let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| {
                let started = hw.now();
                loop {
                    // A hand-over restarts the loop: what is left of --duration.
                    let mut settings = settings;
                    settings.duration_ns = settings
                        .duration_ns
                        .map(|d| d.saturating_sub(hw.now().nanos_since(started)).max(1));
                    let report = run_control_loop(
                        &mut hw,
                        &mut feed,
                        &mut cycle,
                        &settings,
                        &mut loop_control,
                        &mut observers,
                        &mut stats,
                    );
                    let Some(handle) = procedure_handle.as_mut().filter(|_| report.handed_over)
                    else {
                        if report.handed_over {
                            // A hand-over with no procedure to take it: power off as the loop
                            // does when it ends on its own.
                            let _ = hw.disable();
                            let _ = hw.deactivate();
                        }
                        break report;
                    };
                    // Procedure mode: same thread, same priority, same period.
                    let Some(end) = hw.run_procedure(
                        handle,
                        &thread_config,
                        &mut observers,
                        cycle.cycle_count(),
                        cycle.wire_zero(),
                        cycle.safety_state(),
                    ) else {
                        let _ = hw.disable();
                        let _ = hw.deactivate();
                        break report;
                    };
                    let next_cycle = end.next_cycle;
                    match end.recalibration.and_then(|r| {
                        D::from_base_triangle(r.rig).map(|device| (device, r.wire_zero))
                    }) {
                        Some((device, wire_zero)) => {
                            cycle = videt_runtime::setup::control_cycle_for(
                                &thread_config,
                                device,
                                wire_zero,
                                true,
                            );
                            cycle.set_cycle_count(next_cycle);
                            let calibration = CalibrationInForce::of(&cycle);
                            if let Some(t) = observers.telemetry.as_mut() {
                                t.calibration(next_cycle, &calibration);
                            }
                            if let Some(p) = observers.live_calibrations.as_mut() {
                                let _ = p.push(calibration);
                            }
                        }
                        None => {
                            cycle.restart();
                            cycle.set_cycle_count(next_cycle);
                        }
                    }
                    if let Some(state) = end.trip {
                        // A rig found not as configured renders nothing until the service
                        // restarts with its configuration fixed.
                        cycle.trip(state);
                    }
                }
            }));
            match outcome {
                Ok(report) => Ok((report, stats)),
                Err(_) => {
                    // Safe state: power off (the drives also stop by themselves when the host goes
                    // silent).
                    let _ = hw.disable();
                    let _ = hw.deactivate();
                    Err("the control loop panicked; drives powered off".to_string())
                }
            }
        });
    let control = match control {
        Ok(handle) => handle,
        Err(e) => {
            error!("cannot start the control thread: {e}");
            return ExitCode::FAILURE;
        }
    };

    // Supervisor.
    let watchdog = sd_notify::watchdog_enabled();
    let mut ready = false;
    let mut last_status_line = Instant::now();
    let mut last_watchdog = Instant::now();
    let (mut last_cycle, mut last_progress) = (0u64, Instant::now());
    let mut last_safety = SafetyState::Normal;
    let mut last_stale = false;
    // What the hardware last said put it in the current safe state.
    let mut fault_cause: Option<String> = None;
    while !control.is_finished() {
        std::thread::sleep(Duration::from_millis(10));
        if hangup.swap(false, Ordering::Relaxed) {
            warn!("SIGHUP ignored: the configuration is read at start; restart videtd to apply a new one");
        }
        let snapshot = reader.latest();
        let record = snapshot.record;
        if let Some(c) = &colour {
            c.supervise(&record, stop.load(Ordering::Relaxed));
        }
        if record.cycle != last_cycle {
            last_cycle = record.cycle;
            last_progress = Instant::now();
        }
        let running = record.cycle > 0;
        if running && !ready {
            ready = true;
            info!("control loop running, drives enabled");
            let _ = sd_notify::notify(&[
                NotifyState::Ready,
                NotifyState::Status("control loop running"),
            ]);
        }
        if record.safety != last_safety {
            match record.safety.reason() {
                Some(reason) => warn!(
                    reason = reason.as_str(),
                    wire = reason.wire().map(i64::from).unwrap_or(-1),
                    power_off = record.safety.power_off(),
                    "safe state"
                ),
                None => {
                    info!("safety: back to normal operation");
                    fault_cause = None;
                }
            }
            last_safety = record.safety;
        }
        // A cause can be told a tick before the record shows its safe state: it is kept until
        // the service is back to normal.
        if let Some(cause) = tell_fault_causes(&mut fault_causes) {
            fault_cause = Some(cause);
        }
        if let Some(cause) = shared.procedures.as_ref().and_then(|p| p.take_cause()) {
            fault_cause = Some(cause);
        }
        if record.surface_stale != last_stale {
            if record.surface_stale {
                warn!("surface model stale (vision stalled): forces fade to the free-space field");
            } else {
                info!("surface model fresh again: forces restored");
            }
            last_stale = record.surface_stale;
        }
        // Alive: periods keep coming. A safe state the loop holds (an e-stop, a drive fault) is
        // supervised, not hung: the watchdog keeps being petted, so that systemd does not
        // restart the service, which would clear the latch and power the drives on again.
        let healthy = running && last_progress.elapsed() < Duration::from_millis(100);
        if let Some(interval) = watchdog {
            if healthy && last_watchdog.elapsed() >= interval / 2 {
                let _ = sd_notify::notify(&[NotifyState::Watchdog]);
                last_watchdog = Instant::now();
            }
        }
        let dropped = telemetry_writer.as_ref().map_or(0, |w| w.dropped());
        if let Some(writer) = &telemetry_writer {
            log_writer_events(&writer.health(), writer.path());
        }
        let procedure = shared.procedures.as_ref().and_then(|p| {
            if stop.load(Ordering::Relaxed) {
                // Stopping: a procedure under way is cancelled (the loop then ramps out).
                p.control.cancel.store(true, Ordering::Release);
            }
            p.current()
        });
        if let Ok(mut status) = shared.status.lock() {
            *status = StatusReport::from_snapshot(&snapshot, dropped);
            if let Some(writer) = &telemetry_writer {
                status.telemetry_lost = writer.lost();
                status.telemetry_error = writer.failure();
            }
            status.procedure = procedure.map(str::to_string);
            status.fault = fault_cause
                .clone()
                .filter(|_| record.safety.reason().is_some());
            if let Some(watch) = drives_report.as_mut() {
                status.drives = watch.poll(config).to_vec();
            }
        }
        if options.status_lines && running && last_status_line.elapsed() >= Duration::from_secs(1) {
            last_status_line = Instant::now();
            println!(
                "{}{}{}",
                snapshot.line(),
                colour_suffix(colour.as_ref()),
                extra_text()
            );
        }
    }
    let colour_text = colour_suffix(colour.as_ref());
    if let Some(c) = colour {
        c.finish();
    }
    let _ = sd_notify::notify(&[NotifyState::Stopping]);
    let outcome = control.join();
    if let Some(view) = live_view {
        let stats = view.stop();
        info!(
            samples = stats.samples,
            surfaces = stats.surfaces,
            images = stats.images,
            cpu_percent = format!("{:.2}", 100.0 * stats.cpu_share()),
            "live view closed"
        );
    }
    // A cause latched in the last periods (the ramp-out, the drives' shutdown).
    let _ = tell_fault_causes(&mut fault_causes);
    if let Some(server) = server {
        server.stop();
    }
    let panicked = SERVICE_PANICKED.load(Ordering::SeqCst);
    if let Some(writer) = telemetry_writer {
        let (health, path) = (writer.health(), writer.path().to_path_buf());
        let dropped = writer.dropped();
        let reason = end_reason(&outcome, signalled.load(Ordering::SeqCst), panicked);
        let why = reason.to_string();
        let finished = writer.finish(reason);
        // What the last writes and the closing retention said.
        log_writer_events(&health, &path);
        let lost = health.lost();
        let (mb, writer_cpu_s) = (
            health.bytes() as f64 * 1e-6,
            health.writer_cpu().as_secs_f64(),
        );
        match finished {
            Ok(written) => info!(
                written,
                dropped,
                lost,
                mb = format!("{mb:.1}"),
                writer_cpu_s = format!("{writer_cpu_s:.2}"),
                end = %why,
                "telemetry log closed"
            ),
            Err(e) => error!("telemetry log incomplete: {e}"),
        }
    }
    match outcome {
        Ok(Ok((report, stats))) => {
            if options.status_lines {
                println!("{}{colour_text}{}", reader.latest().line(), extra_text());
            }
            log_report(&report, &stats);
            if panicked {
                error!("a thread panicked: stopped in the safe state");
                ExitCode::from(EXIT_PANIC)
            } else {
                info!("stopped: forces ramped out, drives off");
                ExitCode::SUCCESS
            }
        }
        Ok(Err(e)) => {
            error!("{e}");
            ExitCode::from(if panicked { EXIT_PANIC } else { 1 })
        }
        Err(_) => {
            error!("the control thread panicked");
            ExitCode::from(EXIT_PANIC)
        }
    }
}

/// Why the service ended, for the end frame of its session log: from the control thread's
/// outcome, the signal that raised the stop flag (0: none) and whether a thread panicked.
fn end_reason(
    outcome: &std::thread::Result<Result<(LoopReport, LoopStats), String>>,
    signalled: usize,
    panicked: bool,
) -> EndReason {
    let a_panic = || EndReason::FatalFault("a thread panicked: stopped in the safe state".into());
    match outcome {
        Ok(Err(e)) => EndReason::FatalFault(e.clone()),
        Err(_) => EndReason::FatalFault("the control thread panicked".into()),
        Ok(Ok(_)) if panicked => a_panic(),
        Ok(Ok((report, _))) => match report.ended_by {
            LoopEnd::StopFlag => EndReason::Signal(signal_name(signalled)),
            LoopEnd::StopCommand => EndReason::StopRequest,
            LoopEnd::DurationElapsed => EndReason::DurationElapsed,
            LoopEnd::Panic => a_panic(),
            LoopEnd::HandOver => EndReason::FatalFault(
                "a hand-over with no procedure to take it: drives powered off".into(),
            ),
        },
    }
}

/// The name of `signal` (one the service stops on).
fn signal_name(signal: usize) -> String {
    match i32::try_from(signal) {
        Ok(signal_hook::consts::SIGINT) => "SIGINT".into(),
        Ok(signal_hook::consts::SIGTERM) => "SIGTERM".into(),
        _ => format!("signal {signal}"),
    }
}

/// Log what the session log's writer said since the last call: a failing disk once when it
/// starts failing, and once when the writes go through again.
fn log_writer_events(writer: &telemetry::SessionLogHealth, path: &std::path::Path) {
    for event in writer.take_events() {
        match event {
            WriterEvent::Failing { error } => error!(
                log = %path.display(),
                "session log not written: {error}; the control loop goes on, periods are counted as lost and the write is tried again every {} s",
                telemetry::RETRY_EVERY.as_secs()
            ),
            WriterEvent::Removed { path, bytes } => info!(
                removed = %path.display(),
                bytes,
                "session log removed by retention (telemetry.max_total_mb, max_age_days, min_free_mb)"
            ),
            WriterEvent::NotRemoved { path, error } => warn!(
                path = %path.display(),
                "retention could not remove an older session log: {error}"
            ),
            WriterEvent::Writing { lost, after } => warn!(
                log = %path.display(),
                lost,
                "session log written again after {:.1} s: {lost} periods lost",
                after.as_secs_f64()
            ),
        }
    }
}

/// `  colour ...` for the status line, or nothing without a colour thread.
fn colour_suffix(colour: Option<&crate::colour_thread::ColourRuntime>) -> String {
    colour.map_or_else(String::new, |c| format!("  {}", c.status_text()))
}

fn log_report(report: &LoopReport, stats: &LoopStats) {
    info!(
        cycles = report.cycles,
        overruns = report.overruns,
        safety = report.final_safety.as_str(),
        wake_p99_us = stats.latency.quantile_ns(0.99) as f64 * 1e-3,
        wake_max_us = stats.latency.max_ns() as f64 * 1e-3,
        compute_p99_us = stats.compute.quantile_ns(0.99) as f64 * 1e-3,
        "control loop stopped"
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ended(by: LoopEnd) -> std::thread::Result<Result<(LoopReport, LoopStats), String>> {
        let report = LoopReport {
            cycles: 10,
            overruns: 0,
            final_safety: SafetyState::Normal,
            handed_over: by == LoopEnd::HandOver,
            ended_by: by,
        };
        Ok(Ok((report, LoopStats::default())))
    }

    #[test]
    fn the_session_ends_for_what_stopped_the_loop() {
        let sigterm = signal_hook::consts::SIGTERM as usize;
        assert_eq!(
            end_reason(&ended(LoopEnd::StopFlag), sigterm, false),
            EndReason::Signal("SIGTERM".into())
        );
        assert_eq!(
            end_reason(
                &ended(LoopEnd::StopFlag),
                signal_hook::consts::SIGINT as usize,
                false
            ),
            EndReason::Signal("SIGINT".into())
        );
        assert_eq!(
            end_reason(&ended(LoopEnd::StopCommand), 0, false),
            EndReason::StopRequest
        );
        assert_eq!(
            end_reason(&ended(LoopEnd::DurationElapsed), 0, false),
            EndReason::DurationElapsed
        );
        // A panic anywhere wins: the service exits as after a panic.
        for by in [LoopEnd::Panic, LoopEnd::StopFlag] {
            let reason = end_reason(&ended(by), sigterm, true);
            assert_eq!(reason.as_str(), "fatal fault", "{by:?}");
            assert!(reason.to_string().contains("a thread panicked"), "{reason}");
        }
        assert_eq!(
            end_reason(&Ok(Err("cannot start the control loop".into())), 0, false),
            EndReason::FatalFault("cannot start the control loop".into())
        );
        let panicked: std::thread::Result<Result<(LoopReport, LoopStats), String>> =
            Err(Box::new("boom"));
        assert_eq!(
            end_reason(&panicked, 0, true),
            EndReason::FatalFault("the control thread panicked".into())
        );
        assert_eq!(
            end_reason(&ended(LoopEnd::HandOver), 0, false).as_str(),
            "fatal fault"
        );
    }
}
