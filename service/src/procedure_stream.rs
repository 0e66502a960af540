//! The control socket's side of a procedure run on the service's hardware
//! (`{"cmd":"init"}`, `{"cmd":"wire-replace","wire":N}`, `{"cmd":"commission"}`;
//! `docs/control-socket.md`): check the request, take the one procedure slot, hand the request
//! to the control thread, stream its events to the client as JSON lines, pass the client's
//! confirmations back, and save the calibration when the procedure succeeds (atomically, the
//! previous kept as backup) or send the commissioning check's report. The client leaving aborts
//! the procedure.

use std::io::{self, BufRead, BufReader};
use std::os::unix::net::UnixStream;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use serde_json::{json, Value};
use videt_config::calibration::{backup_path, Calibration};
use videt_control::autoinit::{Failure, Stage};

use crate::init::commission::{RigCheck, Verdict};
use crate::init::remote::{saved, ProcedureEvent, ProcedureKind, ProcedurePort, ProcedureSpec};
use crate::init::session::{self, InitError, InitOutcome, Measurement};
use crate::init::twin::{parse_fault, SimFault};
use crate::socket::protocol::{reply, ClientRequest, ProcedureCommand, ProcedureRequest, Response};
use crate::socket::requests::{handle, ServerShared};
use videt_runtime::control_loop::ControlCommand;

/// Exit code and name of a calibration that was measured but not written.
pub const CALIBRATION_WRITE: (u8, &str) = (24, "calibration-write");

/// How often the stream looks for events and client lines.
const POLL: Duration = Duration::from_millis(20);

/// Check a procedure request against the service: its wire, its twin options (only on a twin).
pub fn spec_for(port: &ProcedurePort, request: &ProcedureRequest) -> Result<ProcedureSpec, String> {
    if !port.twin {
        let given = [
            ("sim_seed", request.sim_seed.is_some()),
            ("sim_faults", !request.sim_faults.is_empty()),
            (
                "sim_new_wire_length_m",
                request.sim_new_wire_length_m.is_some(),
            ),
        ];
        if let Some((field, _)) = given.iter().find(|(_, g)| *g) {
            return Err(format!(
                "`{field}`: this service drives the device, not the digital twin"
            ));
        }
    }
    let transmission = videt_runtime::setup::transmission(&port.config);
    let sim_faults = request
        .sim_faults
        .iter()
        .map(|f| parse_fault(f, &transmission))
        .collect::<Result<Vec<_>, _>>()?;
    if sim_faults.iter().any(|f| matches!(f, SimFault::Wiring(_))) {
        return Err(
            "`sim_faults`: a wiring mistake is built into a twin when it starts; the running \
             service's twin is built already (rehearse it without the service: videt ... --sim)"
                .into(),
        );
    }
    if let Some(l) = request.sim_new_wire_length_m {
        if !(l.is_finite() && l > 0.0 && l <= 5.0) {
            return Err(format!(
                "`sim_new_wire_length_m` {l}: must be in (0, 5] metres"
            ));
        }
    }
    let kind = match request.cmd {
        ProcedureCommand::Init => ProcedureKind::Initialize,
        ProcedureCommand::Commission => ProcedureKind::Commission,
        ProcedureCommand::WireReplace => {
            let wire = request.wire.map_or(usize::MAX, usize::from);
            if wire > 2 {
                return Err(format!(
                    "wire {}: wires are 0, 1, 2",
                    request.wire.map_or(-1, i64::from)
                ));
            }
            let current = Calibration::load(&port.calibration_path).ok();
            ProcedureKind::ReplaceWire {
                wire,
                required_length_m: session::required_wire_length_m(&port.config, current.as_ref()),
            }
        }
    };
    Ok(ProcedureSpec {
        kind,
        yes: request.yes,
        sim_seed: request.sim_seed.unwrap_or(1),
        sim_faults,
        sim_new_wire_length_m: request.sim_new_wire_length_m,
    })
}

fn stage_name(stage: Stage) -> (&'static str, Option<u8>) {
    match stage {
        Stage::Settle => ("settle", None),
        Stage::Homing => ("homing", None),
        Stage::Winding(w) => ("winding", Some(w)),
        Stage::Finished => ("finished", None),
        Stage::Failed => ("failed", None),
    }
}

/// The JSON line of an event other than [`ProcedureEvent::Finished`] (see [`done_json`] and
/// [`failed_json`] for the last line).
pub fn event_json(event: &ProcedureEvent) -> Value {
    match event {
        ProcedureEvent::Started { kind, twin } => {
            json!({"ok": true, "event": "started", "procedure": kind.name(), "twin": twin})
        }
        ProcedureEvent::Stage {
            stage,
            counts,
            tension_n,
        } => {
            let (name, wire) = stage_name(*stage);
            json!({"ok": true, "event": "stage", "stage": name, "wire": wire, "counts": counts, "tensions_n": tension_n})
        }
        ProcedureEvent::Progress {
            elapsed_s,
            travel_m,
            tension_n,
        } => {
            json!({"ok": true, "event": "progress", "elapsed_s": elapsed_s, "travel_m": travel_m, "tensions_n": tension_n})
        }
        ProcedureEvent::Message(text) => {
            json!({"ok": true, "event": "message", "message": text.as_str()})
        }
        ProcedureEvent::Prompt { request, confirm } => json!({
            "ok": true,
            "event": "prompt",
            "request": request.name(),
            "wire": request.wire(),
            "confirm": confirm,
            "message": request.instructions(),
        }),
        ProcedureEvent::CheckPrompt { step, confirm } => json!({
            "ok": true,
            "event": "prompt",
            "request": step.name(),
            "wire": step.ring(),
            "confirm": confirm,
            "message": step.instructions(),
        }),
        ProcedureEvent::Checked(check) => checked_json(check),
        ProcedureEvent::Finished(result) => match result.as_ref() {
            Ok(_) => json!({"ok": true, "event": "finished"}),
            Err(e) => failed_json(e.exit_code(), e.name(), &e.to_string()),
        },
    }
}

/// The last line of a successful procedure: the calibration written and where.
pub fn done_json(kind: &'static str, outcome: &InitOutcome, path: &std::path::Path) -> Value {
    json!({
        "ok": true,
        "event": "done",
        "procedure": kind,
        "calibration_file": path.display().to_string(),
        "backup": backup_path(path).display().to_string(),
        "calibration": outcome.calibration,
    })
}

/// The last line of a commissioning check: its steps (each with its verdict, what it measured,
/// its fixes), and what stopped it early (name, exit code and message as a direct run's).
pub fn checked_json(check: &RigCheck) -> Value {
    let stopped = check.stop().map(|(exit_code, name, message)| {
        json!({"error": name, "exit_code": exit_code, "message": message})
    });
    json!({
        "ok": true,
        "event": "checked",
        "procedure": "commission",
        "steps": check.steps,
        "stopped": stopped,
        "as_configured": check.as_configured(),
    })
}

/// The last line of a failed procedure: the same name, exit code and message as a direct run.
pub fn failed_json(exit_code: u8, name: &str, message: &str) -> Value {
    json!({"ok": false, "event": "failed", "error": name, "exit_code": exit_code, "message": message})
}

/// The stream's writer: stops writing (and cancels the procedure) once the client is gone.
struct Stream<'a> {
    writer: &'a mut UnixStream,
    gone: bool,
}

impl Stream<'_> {
    fn send(&mut self, value: &Value, port: &ProcedurePort) {
        if !self.gone && crate::socket::protocol::write_line(self.writer, value).is_err() {
            self.left(port);
        }
    }
    fn left(&mut self, port: &ProcedurePort) {
        self.gone = true;
        port.control.cancel.store(true, Ordering::Release);
    }
}

/// Run one procedure for the client on this connection (see the module documentation). Returns
/// when the procedure has ended (or was refused); the connection may carry more requests.
pub fn serve(
    reader: &mut io::Take<BufReader<UnixStream>>,
    writer: &mut UnixStream,
    request: &ProcedureRequest,
    shared: &ServerShared,
) -> io::Result<()> {
    let Some(port) = shared.procedures.as_ref() else {
        return reply(
            writer,
            &Response::error(if shared.wires == 3 {
                "this service runs no procedures on its hardware".to_string()
            } else {
                format!(
                    "this service runs no procedures: auto-initialization, tension calibration \
                     and wire replacement are the three-wire WireMan's, and its device has {} \
                     wire{}",
                    shared.wires,
                    if shared.wires == 1 { "" } else { "s" }
                )
            }),
        );
    };
    let spec = match spec_for(port, request) {
        Ok(s) => s,
        Err(e) => return reply(writer, &Response::error(e)),
    };
    let Some(mut session) = port.begin() else {
        return reply(
            writer,
            &Response::error(
                "busy: another procedure is running on the service's hardware (one at a time)",
            ),
        );
    };
    let kind = spec.kind;
    tracing::info!(
        procedure = kind.name(),
        "procedure requested on the control socket: ramping the forces out"
    );
    session.submit(spec);
    let pushed = shared
        .commands
        .lock()
        .map(|mut p| p.push(ControlCommand::HandOver).is_ok())
        .unwrap_or(false);
    if !pushed {
        session.withdraw();
        return reply(
            writer,
            &Response::error("busy: the control thread has not taken the previous commands yet"),
        );
    }
    let max_request = port.config.socket.max_request_bytes as u64;
    reader.get_ref().get_ref().set_read_timeout(Some(POLL))?;
    let mut stream = Stream {
        writer,
        gone: false,
    };
    if let ProcedureKind::ReplaceWire {
        wire,
        required_length_m,
    } = kind
    {
        stream.send(
            &json!({"ok": true, "event": "message", "message": format!(
                "replacing wire {wire}: a new yarn must be usable to at least {:.0} mm",
                required_length_m * 1e3
            )}),
            port,
        );
    }
    let asked = Instant::now();
    let hand_over_within = Duration::from_secs_f64(port.config.control.ramp_down_s.max(0.0) + 5.0);
    let mut started = false;
    let mut line = Vec::new();
    loop {
        while let Some(event) = session.next_event() {
            match event {
                ProcedureEvent::Finished(result) => {
                    finish(*result, kind, port, &mut stream);
                    return Ok(());
                }
                ProcedureEvent::Checked(check) => {
                    if let Some(cause) = log_check(&check) {
                        port.tell_cause(cause);
                    }
                    stream.send(&checked_json(&check), port);
                    return Ok(());
                }
                other => {
                    started |= matches!(other, ProcedureEvent::Started { .. });
                    stream.send(&event_json(&other), port);
                }
            }
        }
        if !started && asked.elapsed() > hand_over_within && session.withdraw() {
            let cancelled = InitError::Procedure(Failure::Cancelled);
            stream.send(
                &failed_json(
                    cancelled.exit_code(),
                    cancelled.name(),
                    "the control loop did not hand the motors over (is the service stopping?); nothing was changed",
                ),
                port,
            );
            return Ok(());
        }
        if stream.gone {
            std::thread::sleep(POLL);
            continue;
        }
        reader.set_limit(max_request + 1);
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => stream.left(port),
            Ok(_) if line.ends_with(b"\n") => {
                match ClientRequest::parse(&line) {
                    Ok(ClientRequest::Continue) => {
                        session
                            .control()
                            .confirmations
                            .fetch_add(1, Ordering::AcqRel);
                    }
                    Ok(ClientRequest::Cancel) => {
                        session.control().cancel.store(true, Ordering::Release);
                    }
                    Ok(ClientRequest::Procedure(_)) => stream.send(
                        &json!({"ok": false, "error": "busy: a procedure is running on this connection"}),
                        port,
                    ),
                    _ => {
                        let response = handle(&line, shared);
                        let value = serde_json::to_value(&response).unwrap_or(Value::Null);
                        stream.send(&value, port);
                    }
                }
                line.clear();
            }
            Ok(_) if line.len() as u64 > max_request => {
                line.clear();
                stream.send(
                    &json!({"ok": false, "error": format!("request too large (limit {max_request} bytes)")}),
                    port,
                );
            }
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) => {}
            Err(_) => stream.left(port),
        }
    }
}

/// Log what a commissioning check run by the service found; the cause of the safe state it
/// leaves the service in, if it does.
fn log_check(check: &RigCheck) -> Option<String> {
    let failed: Vec<&str> = check
        .steps
        .iter()
        .filter(|s| s.verdict == Verdict::Fail)
        .map(|s| s.name.as_str())
        .collect();
    if let Some(state) = check.safe_state() {
        tracing::error!(
            failed = ?failed,
            safety = state.as_str(),
            "the commissioning check found the rig not as configured: the drives stay off until \
             videtd is restarted with the configuration fixed (videt commission --write FILE)"
        );
        return Some(format!(
            "commissioning: the rig is not as configured ({}): restart videtd with the fixed configuration",
            failed.join(", ")
        ));
    } else if let Some((_, _, why)) = check.stop() {
        tracing::warn!("the commissioning check stopped early: {why}");
    } else {
        tracing::info!(
            steps = check.steps.len(),
            "the commissioning check found the rig as configured: rendering resumes"
        );
    }
    None
}

/// The procedure ended: save a successful result (unless the client left) and send the last line.
fn finish(
    result: Result<Measurement, InitError>,
    kind: ProcedureKind,
    port: &ProcedurePort,
    stream: &mut Stream<'_>,
) {
    let control = &port.control;
    let path = &port.calibration_path;
    match result {
        Ok(measurement) => {
            // The workspace is computed here, off the control thread (which holds the wires
            // meanwhile).
            let source = if port.twin { "twin" } else { "device" };
            let outcome = session::outcome(&port.config, source, &measurement);
            // Only while the control thread still waits, and only for a client still here.
            let may_save = !stream.gone
                && control
                    .saved
                    .compare_exchange(
                        saved::PENDING,
                        saved::SAVING,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    )
                    .is_ok();
            if !may_save {
                control.saved.store(saved::NOT_SAVED, Ordering::Release);
                return;
            }
            match outcome.calibration.save(path) {
                Ok(()) => {
                    control.saved.store(saved::SAVED, Ordering::Release);
                    let d = outcome.calibration.sides_m;
                    tracing::info!(
                        procedure = kind.name(),
                        file = %path.display(),
                        d01_mm = d[0] * 1e3,
                        d02_mm = d[1] * 1e3,
                        d12_mm = d[2] * 1e3,
                        "calibration written: rendering resumes with it"
                    );
                    stream.send(&done_json(kind.name(), &outcome, path), port);
                }
                Err(e) => {
                    control.saved.store(saved::NOT_SAVED, Ordering::Release);
                    tracing::error!(
                        "the rig was measured but the calibration could not be written: {e}"
                    );
                    let (code, name) = CALIBRATION_WRITE;
                    stream.send(
                        &failed_json(
                            code,
                            name,
                            &format!(
                                "the rig was measured but the calibration could not be written: {e}"
                            ),
                        ),
                        port,
                    );
                }
            }
        }
        Err(e) => {
            tracing::warn!(
                procedure = kind.name(),
                error = e.name(),
                "{e}; rendering resumes with the previous calibration"
            );
            stream.send(
                &failed_json(e.exit_code(), e.name(), &session::failure_message(&e, path)),
                port,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::init::remote::{procedure_channel, Text};
    use crate::init::session::Request;
    use videt_config::Config;

    fn request(line: &str) -> ProcedureRequest {
        match ClientRequest::parse(line.as_bytes()).unwrap() {
            ClientRequest::Procedure(p) => p,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn procedure_requests_parse_strictly() {
        let p = request(r#"{"cmd":"init"}"#);
        assert_eq!(p.cmd, ProcedureCommand::Init);
        assert!(!p.yes && p.sim_faults.is_empty() && p.sim_seed.is_none());
        let p = request(r#"{"cmd":"init","yes":true,"sim_seed":7,"sim_faults":["estop:1"]}"#);
        assert!(p.yes);
        assert_eq!(p.sim_seed, Some(7));
        assert_eq!(p.sim_faults, vec!["estop:1".to_string()]);
        let p = request(r#"{"cmd":"commission","yes":true}"#);
        assert_eq!((p.cmd, p.yes), (ProcedureCommand::Commission, true));
        let p = request(r#"{"cmd":"wire-replace","wire":2,"sim_new_wire_length_m":0.4}"#);
        assert_eq!((p.cmd, p.wire), (ProcedureCommand::WireReplace, Some(2)));
        for (bad, says) in [
            (r#"{"cmd":"init","wire":1}"#, "takes no `wire`"),
            (r#"{"cmd":"wire-replace"}"#, "needs `wire`"),
            (
                r#"{"cmd":"commission","wire":0}"#,
                "`commission` takes no `wire`",
            ),
            (
                r#"{"cmd":"init","sim_new_wire_length_m":1.0}"#,
                "sim_new_wire_length_m",
            ),
            (r#"{"cmd":"status","yes":true}"#, "takes no `yes`"),
            (
                r#"{"cmd":"release","wire":1,"sim_seed":3}"#,
                "takes no `sim_seed`",
            ),
            (r#"{"cmd":"init","force":true}"#, "unknown field"),
            (r#"{"cmd":"init","yes":"sure"}"#, "invalid type"),
        ] {
            let e = ClientRequest::parse(bad.as_bytes()).unwrap_err();
            assert!(e.contains(says), "{bad}: {e}");
        }
        assert_eq!(
            ClientRequest::parse(br#"{"cmd":"continue"}"#),
            Ok(ClientRequest::Continue)
        );
        assert_eq!(
            ClientRequest::parse(br#"{"cmd":"cancel"}"#),
            Ok(ClientRequest::Cancel)
        );
        // The one-reply parser refuses what streams.
        assert!(
            crate::socket::protocol::Request::parse(br#"{"cmd":"init"}"#)
                .unwrap_err()
                .contains("streams")
        );
        // The tool's encoding parses back.
        let p = request(
            r#"{"cmd":"wire-replace","wire":1,"yes":true,"sim_seed":3,"sim_faults":["break:1:2"],"sim_new_wire_length_m":0.5}"#,
        );
        let again = request(&serde_json::to_string(&p).unwrap());
        assert_eq!(p, again);
    }

    #[test]
    fn requests_are_checked_against_the_service() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("calibration.toml");
        let (twin, _h) = procedure_channel(Config::default(), path.clone(), true);
        let (device, _h2) = procedure_channel(Config::default(), path, false);
        let spec = spec_for(
            &twin,
            &request(r#"{"cmd":"init","sim_faults":["estop:2"]}"#),
        )
        .unwrap();
        assert_eq!(spec.kind, ProcedureKind::Initialize);
        assert_eq!(spec.sim_faults.len(), 1);
        assert_eq!(spec.sim_seed, 1);
        let e = spec_for(
            &device,
            &request(r#"{"cmd":"init","sim_faults":["estop:2"]}"#),
        )
        .unwrap_err();
        assert!(e.contains("not the digital twin"), "{e}");
        let e = spec_for(&twin, &request(r#"{"cmd":"init","sim_faults":["melt:2"]}"#)).unwrap_err();
        assert!(e.contains("--sim-fault"), "{e}");
        let spec = spec_for(&twin, &request(r#"{"cmd":"commission"}"#)).unwrap();
        assert_eq!(spec.kind, ProcedureKind::Commission);
        let e = spec_for(
            &twin,
            &request(r#"{"cmd":"commission","sim_faults":["reversed-motor:1"]}"#),
        )
        .unwrap_err();
        assert!(e.contains("built into a twin when it starts"), "{e}");
        let e = spec_for(&twin, &request(r#"{"cmd":"wire-replace","wire":5}"#)).unwrap_err();
        assert!(e.contains("wires are 0, 1, 2"), "{e}");
        let spec = spec_for(&twin, &request(r#"{"cmd":"wire-replace","wire":1}"#)).unwrap();
        match spec.kind {
            ProcedureKind::ReplaceWire {
                wire,
                required_length_m,
            } => {
                assert_eq!(wire, 1);
                assert!(required_length_m > 0.1, "{required_length_m}");
            }
            other => panic!("{other:?}"),
        }
        let e = spec_for(
            &twin,
            &request(r#"{"cmd":"wire-replace","wire":1,"sim_new_wire_length_m":-1}"#),
        )
        .unwrap_err();
        assert!(e.contains("(0, 5]"), "{e}");
    }

    #[test]
    fn events_become_the_documented_lines() {
        let v = event_json(&ProcedureEvent::Started {
            kind: ProcedureKind::Initialize,
            twin: true,
        });
        assert_eq!(
            v,
            json!({"ok": true, "event": "started", "procedure": "init", "twin": true})
        );
        let v = event_json(&ProcedureEvent::Stage {
            stage: Stage::Winding(2),
            counts: [1, -2, 3],
            tension_n: [0.5, 0.25, 1.0],
        });
        assert_eq!(v["stage"], "winding");
        assert_eq!(v["wire"], 2);
        assert_eq!(v["counts"], json!([1, -2, 3]));
        assert_eq!(v["tensions_n"], json!([0.5, 0.25, 1.0]));
        let v = event_json(&ProcedureEvent::Stage {
            stage: Stage::Homing,
            counts: [0; 3],
            tension_n: [0.0; 3],
        });
        assert_eq!(v["wire"], Value::Null);
        let v = event_json(&ProcedureEvent::Message(Text::new("tensioning the wires")));
        assert_eq!(
            v,
            json!({"ok": true, "event": "message", "message": "tensioning the wires"})
        );
        let v = event_json(&ProcedureEvent::Prompt {
            request: Request::FitNewWire { wire: 1 },
            confirm: true,
        });
        assert_eq!(v["request"], "fit-new-wire");
        assert_eq!(v["wire"], 1);
        assert_eq!(v["confirm"], true);
        assert!(v["message"].as_str().unwrap().contains("ring 1"));
        let v = event_json(&ProcedureEvent::CheckPrompt {
            step: crate::init::commission::CommissionStep::PullOutWire {
                ring: 2,
                length_m: 0.1,
            },
            confirm: true,
        });
        assert_eq!(v["request"], "pull-out-wire");
        assert_eq!(v["wire"], 2);
        assert!(v["message"].as_str().unwrap().contains("100 mm"), "{v}");
        let v = event_json(&ProcedureEvent::CheckPrompt {
            step: crate::init::commission::CommissionStep::DetachThimble,
            confirm: false,
        });
        assert_eq!(v["request"], "detach-thimble");
        assert_eq!(v["wire"], Value::Null);
        let v = event_json(&ProcedureEvent::Progress {
            elapsed_s: 1.5,
            travel_m: [0.1, 0.0, -0.1],
            tension_n: [0.4; 3],
        });
        assert_eq!(v["event"], "progress");
        let e = InitError::Procedure(Failure::EmergencyStop);
        let path = std::path::Path::new("/var/lib/videt/calibration.toml");
        let v = failed_json(e.exit_code(), e.name(), &session::failure_message(&e, path));
        assert_eq!(v["ok"], false);
        assert_eq!(v["error"], e.name());
        assert_eq!(v["exit_code"], 10);
        assert!(v["message"]
            .as_str()
            .unwrap()
            .contains("previous calibration (/var/lib/videt/calibration.toml) is unchanged"));
    }
}
