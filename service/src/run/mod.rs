//! Running the service: the control thread, the session log, the control socket, the colour
//! thread, the live view and the supervisor (systemd notify and watchdog, status lines, logging
//! of safety transitions). Generic over the hardware and the surface feed, so the device and the
//! twin run the same service code; [`run_service`] is reached from the launcher's one start.
//!
//! - [`settings`]: how it runs ([`ServiceSettings`]);
//! - [`links`]: what the scene and the hardware add ([`SceneLinks`], [`HardwareReports`]);
//! - [`process`]: the panic hook, the real-time set-up, the signals;
//! - [`session_log`]: the session log's start and end;
//! - [`control_thread`]: the loop and the procedures, in the control thread;
//! - [`supervisor`]: the main thread while the control thread runs;
//! - [`live`]: the live view for Foxglove.

pub mod control_thread;
pub mod links;
pub mod live;
pub mod process;
pub mod session_log;
pub mod settings;
pub mod supervisor;

use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tracing::{error, info, warn};

use crate::init::remote::procedure_channel;
use crate::service_hardware::ServiceHardware;
use crate::socket::{self, ServerSettings, ServerShared, StatusReport};
use videt_runtime::control_loop::{LoopReport, LoopSettings, LoopStats, SERVICE_PANICKED};
use videt_runtime::cycle::ControlCycle;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::snapshot::SurfaceFeed;
use videt_runtime::status::{status_channel, StatusSnapshot};

pub use links::{FaultCauses, HardwareReports, SceneLinks};
pub use process::install_panic_hook;
pub use settings::ServiceSettings;

/// Exit code after a panic in any thread.
pub const EXIT_PANIC: u8 = 70;

/// Run the service on `hw` with surfaces from `feed` and the control cycle `cycle`, the
/// scene's `links` and the hardware's `reports`, until stopped; the exit code.
pub fn run_service<const N: usize, D, H, F>(
    mut hw: H,
    feed: F,
    cycle: ControlCycle<N, D>,
    settings: &ServiceSettings,
    links: SceneLinks,
    reports: HardwareReports,
) -> ExitCode
where
    D: RuntimeDevice<N>,
    H: ServiceHardware<N>,
    F: SurfaceFeed + Send + 'static,
{
    let SceneLinks {
        thimble: vision_thimble,
        status_suffix,
        vision_stall,
        live_image,
    } = links;
    let HardwareReports {
        mut fault_causes,
        drives_report,
    } = reports;
    let mut drives_report = drives_report.map(crate::drive_report::DriveReportWatch::new);
    let status_suffix = move || status_suffix.as_ref().map_or_else(String::new, |f| f());
    install_panic_hook();
    let config = &settings.config;
    let _cpu_latency = process::prepare(config);
    let Some(signals) = process::Signals::install() else {
        return ExitCode::FAILURE;
    };
    let (telemetry_producer, telemetry_writer) = session_log::start(settings, &feed);

    // Control socket, and procedures run on this hardware for its clients.
    let (command_tx, command_rx) = rtrb::RingBuffer::new(64);
    let (procedure_port, procedure_handle) = match &settings.calibration_path {
        Some(path) if settings.socket_path.is_some() && hw.runs_procedures() => {
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
    let server = match &settings.socket_path {
        Some(path) => {
            let server_settings = ServerSettings {
                path: path.clone(),
                max_request_bytes: config.socket.max_request_bytes as usize,
                client_timeout: Duration::from_millis(u64::from(config.socket.client_timeout_ms)),
                max_clients: 8,
            };
            match socket::serve(server_settings, Arc::clone(&shared)) {
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

    // Control thread, and the threads that read what it publishes.
    let loop_settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: settings.duration_s.map(|d| (d * 1e9) as u64),
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
    let colour = settings.colour.as_ref().and_then(|source| {
        let colour_priority = Some(priority.saturating_sub(10).max(1));
        crate::colour_thread::ColourRuntime::start(source, thimble_reader, colour_priority)
            .map_err(|e| warn!("colour rendering disabled: {e}"))
            .ok()
    });
    let thimble_publisher = colour.is_some().then_some(thimble_publisher);
    let (live_publisher, live_calibrations, live_view) = match &settings.live {
        Some(live) => live::start::<N, D, F>(
            live,
            config,
            &cycle,
            &feed,
            live_image,
            telemetry_writer.as_ref().map(|w| w.health()),
        ),
        None => (None, None, None),
    };
    let control = control_thread::spawn(
        control_thread::ControlThread {
            hw,
            feed,
            cycle,
            settings: loop_settings,
            config: config.clone(),
            observers: control_thread::Observers {
                status: publisher,
                telemetry: telemetry_producer,
                thimble: thimble_publisher,
                vision_thimble,
                live: live_publisher,
                live_calibrations,
            },
            commands: command_rx,
            procedures: procedure_handle,
            stop: Arc::clone(&signals.stop),
        },
        priority,
        usize::try_from(config.realtime.control_cpu).ok(),
    );
    let control = match control {
        Ok(handle) => handle,
        Err(e) => {
            error!("cannot start the control thread: {e}");
            return ExitCode::FAILURE;
        }
    };

    supervisor::supervise(
        supervisor::Supervised {
            config,
            status: &mut reader,
            shared: &shared,
            stop: &signals.stop,
            hangup: &signals.hangup,
            colour: colour.as_ref(),
            telemetry: telemetry_writer.as_ref(),
            fault_causes: &mut fault_causes,
            drives_report: drives_report.as_mut(),
            status_lines: settings.status_lines,
            status_suffix: &status_suffix,
        },
        &|| control.is_finished(),
    );

    // The end: the colour thread, the control thread, the live view, the socket, the log.
    let colour_text = supervisor::colour_suffix(colour.as_ref());
    if let Some(c) = colour {
        c.finish();
    }
    let _ = sd_notify::notify(&[sd_notify::NotifyState::Stopping]);
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
    let _ = links::tell_fault_causes(&mut fault_causes);
    if let Some(server) = server {
        server.stop();
    }
    let panicked = SERVICE_PANICKED.load(Ordering::SeqCst);
    if let Some(writer) = telemetry_writer {
        session_log::close(
            writer,
            &outcome,
            signals.signalled.load(Ordering::SeqCst),
            panicked,
        );
    }
    match outcome {
        Ok(Ok((report, stats))) => {
            if settings.status_lines {
                println!("{}{colour_text}{}", reader.latest().line(), status_suffix());
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
