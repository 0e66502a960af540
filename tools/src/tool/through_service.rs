//! Procedures run by the running `videtd` on its own hardware, through its control socket
//! (`docs/control-socket.md`): send the request, print the stream of progress lines as a direct
//! run prints them, pass the technician's confirmations back, and return the calibration the
//! service wrote — or the same error (name, message, exit code) a direct run gives.

use std::io::{BufRead, BufReader, IsTerminal};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::Duration;

use serde_json::Value;
use videt_config::calibration::Calibration;
use videt_config::Config;

use super::device::{stop_on_signals, DeviceArgs, Exit, EXIT_MOTORS_BUSY, EXIT_USAGE};
use videt_service::init::commission::StepReport;
use videt_service::socket::{write_line, ProcedureCommand, ProcedureRequest};

/// The connection to the service broke before the procedure ended.
pub const EXIT_SERVICE_LOST: u8 = 26;

/// A procedure the service finished: the calibration it wrote, and where.
#[derive(Debug, Clone, PartialEq)]
pub struct Done {
    /// The new calibration.
    pub calibration: Calibration,
    /// The service's calibration file.
    pub path: PathBuf,
}

impl DeviceArgs {
    /// The request for the service, from these options (twin options only with --sim; the
    /// service's twin has its own guide points).
    pub fn service_request(
        &self,
        config: &Config,
        cmd: ProcedureCommand,
        wire: Option<u8>,
        sim_new_wire_length_m: Option<f64>,
    ) -> Result<ProcedureRequest, Exit> {
        // The same argument checks as a direct run, before anything moves.
        self.twin_setup(config)?;
        if self.sim_guides.is_some() {
            return Err(Exit::new(
                EXIT_USAGE,
                "usage",
                "--sim-guides: the running videtd's twin has its own guide points (set them with videtd --sim-guides)",
            ));
        }
        Ok(ProcedureRequest {
            cmd,
            wire,
            yes: self.yes,
            sim_seed: self.sim.then_some(self.sim_seed),
            sim_faults: self.sim_fault.clone(),
            sim_new_wire_length_m,
        })
    }
}

fn lost(message: impl Into<String>) -> Exit {
    Exit::new(EXIT_SERVICE_LOST, "service-lost", message)
}

/// A commissioning check the service ran on its rig.
#[derive(Debug, Clone, PartialEq)]
pub struct Checked {
    /// The steps, in the order they ran.
    pub steps: Vec<StepReport>,
    /// What stopped the check early: its exit code and message, as a direct run's.
    pub stopped: Option<(u8, String)>,
}

/// How a procedure run by the service ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Finished {
    /// It measured the rig and the service wrote the calibration.
    Calibrated(Box<Done>),
    /// The commissioning check ran.
    Checked(Checked),
}

/// What one line of the stream asks of the client.
#[derive(Debug, PartialEq)]
enum Step {
    /// Keep reading.
    Next,
    /// Wait for the technician's Enter, then send `continue`.
    Confirm,
    /// The technician cannot confirm (no terminal): cancel.
    Cancel,
    /// The procedure ended.
    Done(Finished),
}

/// Act on one line of the stream: print what a direct run prints, say what comes next.
fn on_line(line: &Value, twin: &mut bool) -> Result<Step, Exit> {
    let text = |key: &str| line[key].as_str().unwrap_or_default().to_string();
    match line["event"].as_str() {
        None => {
            // A one-line refusal (busy, a bad request).
            let error = text("error");
            let (code, name) = if error.starts_with("busy") {
                (EXIT_MOTORS_BUSY, "motors-busy")
            } else {
                (EXIT_USAGE, "usage")
            };
            Err(Exit::new(code, name, format!("videtd refused: {error}")))
        }
        Some("started") => {
            *twin = line["twin"].as_bool().unwrap_or(false);
            eprintln!(
                "videt: videtd ramped its forces out and runs the procedure on its {}",
                if *twin { "digital twin" } else { "hardware" }
            );
            Ok(Step::Next)
        }
        Some("message") => {
            eprintln!("videt: {}", text("message"));
            Ok(Step::Next)
        }
        Some("prompt") => {
            let confirm = line["confirm"].as_bool().unwrap_or(true);
            if !*twin || confirm {
                eprintln!("videt: {}", text("message"));
            }
            if !confirm {
                Ok(Step::Next)
            } else if std::io::stdin().is_terminal() {
                Ok(Step::Confirm)
            } else {
                Ok(Step::Cancel)
            }
        }
        Some("done") => {
            let calibration: Calibration = serde_json::from_value(line["calibration"].clone())
                .map_err(|e| lost(format!("videtd's calibration record is unreadable: {e}")))?;
            Ok(Step::Done(Finished::Calibrated(Box::new(Done {
                calibration,
                path: PathBuf::from(text("calibration_file")),
            }))))
        }
        Some("checked") => {
            let steps: Vec<StepReport> = serde_json::from_value(line["steps"].clone())
                .map_err(|e| lost(format!("videtd's check report is unreadable: {e}")))?;
            let stopped = line["stopped"].as_object().map(|s| {
                let code = s["exit_code"].as_u64().and_then(|c| u8::try_from(c).ok());
                let message = s["message"].as_str().unwrap_or_default().to_string();
                (code.unwrap_or(1), message)
            });
            Ok(Step::Done(Finished::Checked(Checked { steps, stopped })))
        }
        Some("failed") => {
            let code = line["exit_code"]
                .as_u64()
                .and_then(|c| u8::try_from(c).ok())
                .unwrap_or(1);
            Err(Exit::new(code, text("error"), text("message")))
        }
        Some(_) => Ok(Step::Next),
    }
}

/// Run the measuring `request` (`init`, `wire-replace`) on the service listening on `socket`:
/// the calibration it wrote. Ctrl-C (or SIGTERM) cancels the procedure; the service then ends it
/// safely and keeps its previous calibration.
pub fn run(socket: &Path, request: &ProcedureRequest) -> Result<Done, Exit> {
    match run_procedure(socket, request)? {
        Finished::Calibrated(done) => Ok(*done),
        Finished::Checked(_) => Err(lost("videtd sent a check's report for a measurement")),
    }
}

/// Run the commissioning check on the service listening on `socket`: its report. Ctrl-C (or
/// SIGTERM) cancels it; the service then leaves every motor idle.
pub fn run_check(socket: &Path, request: &ProcedureRequest) -> Result<Checked, Exit> {
    match run_procedure(socket, request)? {
        Finished::Checked(checked) => Ok(checked),
        Finished::Calibrated(_) => Err(lost("videtd sent a calibration for a check")),
    }
}

/// Run `request` on the service listening on `socket`; how it ended.
fn run_procedure(socket: &Path, request: &ProcedureRequest) -> Result<Finished, Exit> {
    let stop = stop_on_signals();
    let mut stream = UnixStream::connect(socket)
        .map_err(|e| lost(format!("cannot reach videtd on {}: {e}", socket.display())))?;
    let send = |stream: &mut UnixStream, value: &Value| -> Result<(), Exit> {
        write_line(stream, value).map_err(|e| lost(format!("videtd's control socket: {e}")))
    };
    let request_value = serde_json::to_value(request).map_err(|e| lost(e.to_string()))?;
    send(&mut stream, &request_value)?;
    stream
        .set_read_timeout(Some(Duration::from_millis(100)))
        .map_err(|e| lost(e.to_string()))?;
    let mut reader = BufReader::new(
        stream
            .try_clone()
            .map_err(|e| lost(format!("videtd's control socket: {e}")))?,
    );
    let mut line = Vec::new();
    let mut enter: Option<mpsc::Receiver<()>> = None;
    let mut cancel_sent = false;
    let mut twin = false;
    loop {
        if stop.load(Ordering::Relaxed) && !cancel_sent {
            eprintln!("videt: cancelling: videtd ends the procedure safely");
            send(&mut stream, &serde_json::json!({"cmd": "cancel"}))?;
            cancel_sent = true;
        }
        if enter.as_ref().is_some_and(|rx| rx.try_recv().is_ok()) {
            enter = None;
            send(&mut stream, &serde_json::json!({"cmd": "continue"}))?;
        }
        match reader.read_until(b'\n', &mut line) {
            Ok(0) => {
                return Err(lost(
                    "videtd closed the connection before the procedure ended (is it still running? `videt status`)",
                ))
            }
            Ok(_) if line.ends_with(b"\n") => {
                let value: Value = serde_json::from_slice(&line)
                    .map_err(|e| lost(format!("videtd sent an unreadable line: {e}")))?;
                line.clear();
                match on_line(&value, &mut twin)? {
                    Step::Next => {}
                    Step::Done(done) => return Ok(done),
                    Step::Cancel => {
                        if !cancel_sent {
                            send(&mut stream, &serde_json::json!({"cmd": "cancel"}))?;
                            cancel_sent = true;
                        }
                    }
                    Step::Confirm => enter = Some(super::device::enter_pressed()),
                }
            }
            Ok(_) => {}
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) => {}
            Err(e) => return Err(lost(format!("videtd's control socket: {e}"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn the_stream_becomes_the_direct_runs_output_and_errors() {
        let mut twin = false;
        assert_eq!(
            on_line(
                &json!({"ok": true, "event": "started", "procedure": "init", "twin": true}),
                &mut twin
            )
            .unwrap(),
            Step::Next
        );
        assert!(twin);
        assert_eq!(
            on_line(
                &json!({"ok": true, "event": "prompt", "request": "connect-wires", "wire": null, "confirm": false, "message": "m"}),
                &mut twin
            )
            .unwrap(),
            Step::Next
        );
        let e = on_line(
            &json!({"ok": false, "event": "failed", "error": "sides-disagree", "exit_code": 14, "message": "side d01 ..."}),
            &mut twin,
        )
        .unwrap_err();
        assert_eq!(
            (e.code, e.name.as_ref(), e.message.as_str()),
            (14, "sides-disagree", "side d01 ...")
        );
        let e = on_line(
            &json!({"ok": false, "error": "busy: another procedure"}),
            &mut twin,
        )
        .unwrap_err();
        assert_eq!(e.code, EXIT_MOTORS_BUSY);
        let e = on_line(
            &json!({"ok": false, "error": "malformed request: x"}),
            &mut twin,
        )
        .unwrap_err();
        assert_eq!(e.code, EXIT_USAGE);
        let e = on_line(
            &json!({"ok": true, "event": "done", "calibration": {"format": "x"}}),
            &mut twin,
        )
        .unwrap_err();
        assert_eq!(e.code, EXIT_SERVICE_LOST);
    }

    #[test]
    fn a_check_report_from_the_service_becomes_the_direct_runs_steps() {
        use videt_config::edit::{Fix, FixValue};
        use videt_service::init::commission::{RigCheck, Verdict};
        let check = RigCheck {
            steps: vec![
                StepReport::pass("estop.released", "the e-stop input reads released"),
                StepReport::fail(
                    "drive1.direction",
                    "a positive torque unwinds wire 1",
                    vec![Fix::new(
                        "drives.motor_reversed",
                        Some(1),
                        FixValue::Bool(true),
                    )],
                ),
            ],
            stopped: Some(videt_control::autoinit::Failure::Cancelled),
            detail: None,
        };
        let line = videt_service::procedure_stream::checked_json(&check);
        let mut twin = true;
        match on_line(&line, &mut twin).unwrap() {
            Step::Done(finished) => match finished {
                Finished::Checked(c) => {
                    assert_eq!(c.steps, check.steps);
                    assert_eq!(c.steps[1].verdict, Verdict::Fail);
                    let (code, message) = c.stopped.unwrap();
                    assert_eq!(code, 20);
                    assert!(!message.is_empty());
                }
                other => panic!("{other:?}"),
            },
            other => panic!("{other:?}"),
        }
        let e = on_line(
            &json!({"ok": true, "event": "checked", "steps": [{"name": 3}]}),
            &mut twin,
        )
        .unwrap_err();
        assert_eq!(e.code, EXIT_SERVICE_LOST);
    }
}
