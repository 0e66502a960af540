//! The supervisor, on the service's main thread while the control thread runs: systemd's
//! READY=1 and watchdog, the safety transitions and the hardware's causes logged, the status
//! the control socket serves, one status line per second, the colour thread supervised.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sd_notify::NotifyState;
use tracing::{info, warn};
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_runtime::status::StatusReader;
use videt_runtime::telemetry::TelemetryWriter;

use super::links::{tell_fault_causes, FaultCauses};
use super::session_log::log_writer_events;
use crate::colour_thread::ColourRuntime;
use crate::drive_report::DriveReportWatch;
use crate::socket::{ServerShared, StatusReport};

/// What the supervisor watches and keeps up to date.
pub struct Supervised<'a> {
    /// The configuration in force.
    pub config: &'a Config,
    /// The control thread's status.
    pub status: &'a mut StatusReader,
    /// What the control socket serves.
    pub shared: &'a ServerShared,
    /// The stop flag (a procedure under way is cancelled once it is raised).
    pub stop: &'a AtomicBool,
    /// Raised by SIGHUP.
    pub hangup: &'a AtomicBool,
    /// The colour thread, if any.
    pub colour: Option<&'a ColourRuntime>,
    /// The session log's writer, if any.
    pub telemetry: Option<&'a TelemetryWriter>,
    /// The hardware's causes of its safe states.
    pub fault_causes: &'a mut Option<FaultCauses>,
    /// The drives' start-up report.
    pub drives_report: Option<&'a mut DriveReportWatch>,
    /// Print a status line every second.
    pub status_lines: bool,
    /// Text after each status line (the scene's).
    pub status_suffix: &'a dyn Fn() -> String,
}

/// Supervise until `finished` says the control thread ended.
pub fn supervise(s: Supervised<'_>, finished: &dyn Fn() -> bool) {
    let watchdog = sd_notify::watchdog_enabled();
    let mut ready = false;
    let mut last_status_line = Instant::now();
    let mut last_watchdog = Instant::now();
    let (mut last_cycle, mut last_progress) = (0u64, Instant::now());
    let mut last_safety = SafetyState::Normal;
    let mut last_stale = false;
    let Supervised {
        config,
        status: reader,
        shared,
        stop,
        hangup,
        colour,
        telemetry: telemetry_writer,
        fault_causes,
        mut drives_report,
        status_lines,
        status_suffix,
    } = s;
    // What the hardware last said put it in the current safe state.
    let mut fault_cause: Option<String> = None;
    while !finished() {
        std::thread::sleep(Duration::from_millis(10));
        if hangup.swap(false, Ordering::Relaxed) {
            warn!("SIGHUP ignored: the configuration is read at start; restart videtd to apply a new one");
        }
        let snapshot = reader.latest();
        let record = snapshot.record;
        if let Some(c) = colour {
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
        if let Some(cause) = tell_fault_causes(fault_causes) {
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
        let dropped = telemetry_writer.map_or(0, |w| w.dropped());
        if let Some(writer) = telemetry_writer {
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
            if let Some(writer) = telemetry_writer {
                status.telemetry_lost = writer.lost();
                status.telemetry_error = writer.failure();
            }
            status.procedure = procedure.map(str::to_string);
            status.fault = fault_cause
                .clone()
                .filter(|_| record.safety.reason().is_some());
            if let Some(watch) = drives_report.as_deref_mut() {
                status.drives = watch.poll(config).to_vec();
            }
        }
        if status_lines && running && last_status_line.elapsed() >= Duration::from_secs(1) {
            last_status_line = Instant::now();
            println!(
                "{}{}{}",
                snapshot.line(),
                colour_suffix(colour),
                status_suffix()
            );
        }
    }
}

/// `  colour ...` for the status line, or nothing without a colour thread.
pub fn colour_suffix(colour: Option<&ColourRuntime>) -> String {
    colour.map_or_else(String::new, |c| format!("  {}", c.status_text()))
}
