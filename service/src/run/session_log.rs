//! The session log: started in the telemetry directory with what runs and the feed's surfaces,
//! its writer's events logged while it runs, and closed with why the session ended.

use std::path::Path;

use tracing::{error, info, warn};
use videt_runtime::control_loop::{LoopEnd, LoopReport, LoopStats};
use videt_runtime::snapshot::SurfaceFeed;
use videt_runtime::telemetry::{
    self, EndReason, LogHeader, TelemetryProducer, TelemetryWriter, WriterEvent,
};

use super::ServiceSettings;

/// What the control thread's periods go through when a session log is written.
pub type ControlThreadOutcome = std::thread::Result<Result<(LoopReport, LoopStats), String>>;

/// Start the session log of `settings` in its telemetry directory: the producer the control
/// thread records into and the writer; `(None, None)` when there is none or it cannot be
/// written (said so).
pub fn start<F: SurfaceFeed>(
    settings: &ServiceSettings,
    feed: &F,
) -> (Option<TelemetryProducer>, Option<TelemetryWriter>) {
    let Some(dir) = &settings.telemetry_dir else {
        return (None, None);
    };
    let config = &settings.config;
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
                session: Some(telemetry::SessionInfo::new(
                    &settings.description,
                    config.clone(),
                )),
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
            (Some(producer), Some(writer))
        }
        Err(e) => {
            warn!("telemetry disabled: cannot write {}: {e}", path.display());
            (None, None)
        }
    }
}

/// Close the session log with why the session ended (the control thread's `outcome`, the
/// signal that stopped it, whether a thread panicked) and say what it holds.
pub fn close(
    writer: TelemetryWriter,
    outcome: &ControlThreadOutcome,
    signalled: usize,
    panicked: bool,
) {
    let (health, path) = (writer.health(), writer.path().to_path_buf());
    let dropped = writer.dropped();
    let reason = end_reason(outcome, signalled, panicked);
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

/// Why the service ended, for the end frame of its session log: from the control thread's
/// outcome, the signal that raised the stop flag (0: none) and whether a thread panicked.
fn end_reason(outcome: &ControlThreadOutcome, signalled: usize, panicked: bool) -> EndReason {
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
pub fn log_writer_events(writer: &telemetry::SessionLogHealth, path: &Path) {
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

#[cfg(test)]
mod tests {
    use super::*;
    use videt_control::safety::SafetyState;

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
