//! `videt soak`: run `videtd` on the CAN twin for a long time with faults injected at random,
//! recover each through its documented procedure, and check that every fault reached its safe
//! state within two periods of being visible to the control cycle, that nothing panicked, that
//! memory, file descriptors and threads stay flat, and that every session log is complete (read
//! whole, closed by its end frame, gaps equal to the drops reported) and replays bit for bit. One table at the end; exit 0 only when every check holds.
//!
//! Recovery, as `docs/control-socket.md` documents it: a fault that only holds the wires at
//! minimum tension (a tension sensor) is cleared with `videt service reset-faults` once its
//! cause is gone; a fault that powers the drives off (a broken wire, the e-stop, a drive's
//! emergency, a lost heartbeat, the bus off) needs the service restarted once the cause is
//! gone (`systemctl restart videtd`; here: stop, start).

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use clap::Args;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use videt_runtime::cycle::{CycleRecord, EStopReading};
use videt_runtime::telemetry::{read_log, Log};
use videt_service::socket::{request, Request, StatusReport};

use super::ToolResult;

mod host_stall;
use host_stall::{safe_state_entries, SafeStateEntry, StolenTime};

/// Soak the service on the twin with random faults.
#[derive(Debug, Args)]
pub struct SoakArgs {
    /// How long to run, seconds.
    #[arg(long, default_value_t = 3600.0)]
    pub duration: f64,
    /// Mean time between faults, seconds.
    #[arg(long, default_value_t = 15.0)]
    pub fault_every: f64,
    /// Least time between faults that power the drives off (each restarts the service), seconds.
    #[arg(long, default_value_t = 300.0)]
    pub power_off_every: f64,
    /// Seed of the fault sequence.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for the sockets, session logs and service output (default: a new temporary
    /// directory, kept).
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// The videtd to run (default: the one beside this videt).
    #[arg(long, value_name = "FILE")]
    pub videtd: Option<PathBuf>,
    /// Which twin: `can` (drives on a simulated CAN bus) or `hal`.
    #[arg(long, default_value = "can")]
    pub sim: String,
    /// What the twin's operator touches: `box` (a relief rebuilt every second by a vision
    /// thread, which can stall) or `wall`.
    #[arg(long, default_value = "box")]
    pub scene: String,
}

/// A fault the soak injects.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    SensorLoss(u8),
    WireBreak(u8),
    EStop,
    Emcy(u8),
    HeartbeatLoss(u8),
    BusOff,
    SocketAbuse,
    Hangup,
    VisionStall,
}

impl Fault {
    fn name(self) -> &'static str {
        match self {
            Fault::SensorLoss(_) => "sensor loss",
            Fault::WireBreak(_) => "wire break",
            Fault::EStop => "e-stop",
            Fault::Emcy(_) => "EMCY",
            Fault::HeartbeatLoss(_) => "heartbeat loss",
            Fault::BusOff => "bus-off",
            Fault::SocketAbuse => "socket abuse",
            Fault::Hangup => "SIGHUP",
            Fault::VisionStall => "vision stall",
        }
    }
    /// The `sim-fault` that causes it and the one that removes its cause.
    fn injections(self) -> (Option<String>, Option<String>) {
        match self {
            Fault::SensorLoss(w) => (Some(format!("sensor:{w}")), Some("sensor-restore".into())),
            Fault::WireBreak(w) => (Some(format!("break:{w}")), None),
            Fault::EStop => (Some("estop".into()), Some("estop-release".into())),
            Fault::Emcy(w) => (Some(format!("emcy:{w}")), Some(format!("emcy-clear:{w}"))),
            Fault::HeartbeatLoss(w) => (
                Some(format!("heartbeat:{w}")),
                Some(format!("heartbeat-restore:{w}")),
            ),
            Fault::BusOff => (Some("bus-off".into()), Some("bus-on".into())),
            Fault::VisionStall => (Some("vision-stall".into()), Some("vision-resume".into())),
            Fault::SocketAbuse | Fault::Hangup => (None, None),
        }
    }
    /// The safe state it must reach (`None`: none, the service carries on).
    fn expected(self) -> Option<&'static [&'static str]> {
        match self {
            Fault::SensorLoss(_) => Some(&["sensor-fault"]),
            Fault::WireBreak(_) => Some(&["wire-break", "over-speed", "drive-fault"]),
            Fault::EStop => Some(&["e-stop"]),
            Fault::Emcy(_) | Fault::HeartbeatLoss(_) | Fault::BusOff => Some(&["drive-fault"]),
            Fault::SocketAbuse | Fault::Hangup | Fault::VisionStall => None,
        }
    }
    fn powers_off(self) -> bool {
        !matches!(
            self,
            Fault::SensorLoss(_) | Fault::SocketAbuse | Fault::Hangup | Fault::VisionStall
        )
    }
    /// Whether a period's inputs show the fault (the control cycle can see it).
    fn visible_in(self, r: &CycleRecord) -> bool {
        let i = &r.inputs;
        let drive_fault = !i.drives_read_ok
            || i.drives
                .iter()
                .any(|d| d.state == videt_hal::DriveState::Fault);
        match self {
            Fault::SensorLoss(_) => !i.tensions_read_ok,
            Fault::EStop => i.estop != EStopReading::Released,
            Fault::Emcy(_) | Fault::HeartbeatLoss(_) | Fault::BusOff => drive_fault,
            // A broken wire is seen by the supervisor itself (a wire wound in without tension).
            Fault::WireBreak(_) => r.safety.reason().is_some(),
            Fault::SocketAbuse | Fault::Hangup | Fault::VisionStall => false,
        }
    }
}

/// One fault as it went.
#[derive(Debug, Clone)]
struct Trial {
    fault: Fault,
    instance: usize,
    /// Seconds from the soak's start.
    at_s: f64,
    /// The safe state seen in the status, and how long after injection, seconds.
    reached: Option<(String, f64)>,
    recovered: bool,
    /// Periods from the first period whose inputs show the fault to the first period in a safe
    /// state (from the session log).
    periods_to_safe: Option<u64>,
    note: String,
}

/// Resources of a service run at one time.
#[derive(Debug, Clone, Copy)]
struct Sample {
    age_s: f64,
    rss_kb: u64,
    fds: usize,
    threads: usize,
}

/// A safe state nobody injected, as the soak found it before a trial.
#[derive(Debug, Clone)]
struct Unprompted {
    /// Soak time when found, seconds.
    at_s: f64,
    /// The service run.
    run: usize,
    /// Time since that run started when found, seconds.
    run_s: f64,
    /// The safe state's name.
    state: String,
}

/// One run of the service.
struct Instance {
    child: Child,
    started: Instant,
    samples: Vec<Sample>,
    stderr: PathBuf,
}

fn proc_sample(pid: u32) -> Option<(u64, usize, usize)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<u64>().ok())
    };
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?.count();
    Some((field("VmRSS:")?, fds, field("Threads:")? as usize))
}

struct Soak {
    sim: String,
    scene: String,
    dir: PathBuf,
    socket: PathBuf,
    videtd: PathBuf,
    start: Instant,
    instances: Vec<Instance>,
    trials: Vec<Trial>,
    /// Safe states nobody injected: (seconds from the start, run, state).
    unprompted: Vec<Unprompted>,
    /// The hypervisor's stolen time, sampled all along.
    stolen: StolenTime,
}

impl Soak {
    /// Before a fault: the service must be in normal operation. A safe state nobody caused (a
    /// host too loaded to run the twin's drives in time, a bug) is recorded and recovered from,
    /// so the next fault starts clean.
    fn check_unprompted(&mut self) -> Result<(), String> {
        let Some(status) = self.status() else {
            return Err("the service does not answer its socket".into());
        };
        if status.safety == "normal" {
            return Ok(());
        }
        let run = self.instances.len() - 1;
        self.unprompted.push(Unprompted {
            at_s: self.start.elapsed().as_secs_f64(),
            run,
            run_s: self.instances[run].started.elapsed().as_secs_f64(),
            state: status.safety.clone(),
        });
        if status.power_off {
            self.stop_instance()?;
            self.start_instance()
        } else {
            let _ = request(&self.socket, &Request::ResetFaults, Duration::from_secs(2));
            self.wait_status(Duration::from_secs(5), |s| s.safety == "normal")
                .map(|_| ())
                .ok_or_else(|| format!("the service stays in {} after reset-faults", status.safety))
        }
    }

    fn status(&self) -> Option<StatusReport> {
        request(&self.socket, &Request::Status, Duration::from_secs(2))
            .ok()
            .and_then(|r| r.status)
    }

    fn wait_status(
        &self,
        within: Duration,
        ok: impl Fn(&StatusReport) -> bool,
    ) -> Option<StatusReport> {
        let deadline = Instant::now() + within;
        while Instant::now() < deadline {
            if let Some(s) = self.status().filter(|s| ok(s)) {
                return Some(s);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        None
    }

    fn sim_fault(&self, spec: &str) -> Result<(), String> {
        let r = request(
            &self.socket,
            &Request::SimFault {
                fault: spec.to_string(),
            },
            Duration::from_secs(2),
        )
        .map_err(|e| e.to_string())?;
        if r.ok {
            Ok(())
        } else {
            Err(r.error.unwrap_or_default())
        }
    }

    fn start_instance(&mut self) -> Result<(), String> {
        let n = self.instances.len();
        let stderr = self.dir.join(format!("videtd-{n}.log"));
        let _ = std::fs::remove_file(&self.socket);
        let child = Command::new(&self.videtd)
            .args(["--sim", &self.sim, "--scene", &self.scene, "--socket"])
            .arg(&self.socket)
            .arg("--telemetry-dir")
            .arg(self.dir.join(format!("logs-{n}")))
            .env("RUST_LOG", "info")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).map_err(|e| e.to_string())?)
            .spawn()
            .map_err(|e| format!("{}: {e}", self.videtd.display()))?;
        self.instances.push(Instance {
            child,
            started: Instant::now(),
            samples: Vec::new(),
            stderr,
        });
        self.wait_status(Duration::from_secs(30), |s| {
            s.cycles > 500 && s.safety == "normal" && s.force_n > 0.0
        })
        .map(|_| ())
        .ok_or_else(|| format!("videtd instance {n} did not start rendering"))
    }

    fn stop_instance(&mut self) -> Result<(), String> {
        let _ = request(&self.socket, &Request::Stop, Duration::from_secs(2));
        let inst = self.instances.last_mut().ok_or("no instance")?;
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(status) = inst.child.try_wait().map_err(|e| e.to_string())? {
                return if status.success() {
                    Ok(())
                } else {
                    Err(format!("videtd exited with {status}"))
                };
            }
            if Instant::now() > deadline {
                let _ = inst.child.kill();
                return Err("videtd did not stop within 20 s".into());
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn sample(&mut self) {
        if let Some(inst) = self.instances.last_mut() {
            if let Some((rss_kb, fds, threads)) = proc_sample(inst.child.id()) {
                inst.samples.push(Sample {
                    age_s: inst.started.elapsed().as_secs_f64(),
                    rss_kb,
                    fds,
                    threads,
                });
            }
        }
    }

    /// Garbage, a 10 MB line, 100 000-deep JSON, NaN, wrong types: each refused, the service
    /// unmoved.
    fn abuse_socket(&self) -> Result<String, String> {
        let deep = format!("{}{}", "[".repeat(100_000), "]".repeat(100_000));
        let huge = "x".repeat(10 << 20);
        let lines: [&[u8]; 6] = [
            b"\x00\xff garbage \x01",
            huge.as_bytes(),
            deep.as_bytes(),
            br#"{"cmd":"release","wire":NaN}"#,
            br#"{"cmd":"release","wire":"one"}"#,
            br#"{"cmd":"sim-fault"}"#,
        ];
        let mut refused = 0;
        for line in lines {
            let Ok(mut stream) = UnixStream::connect(&self.socket) else {
                continue;
            };
            stream
                .set_read_timeout(Some(Duration::from_secs(3)))
                .map_err(|e| e.to_string())?;
            // A server that closes on an oversized line may cut the write short: that is a
            // refusal too.
            let _ = stream
                .write_all(line)
                .and_then(|()| stream.write_all(b"\n"));
            let mut reply = String::new();
            let _ = BufReader::new(&stream).read_line(&mut reply);
            let ok = serde_json::from_str::<serde_json::Value>(&reply)
                .ok()
                .and_then(|v| v["ok"].as_bool());
            if ok != Some(true) {
                refused += 1;
            }
        }
        if refused == lines.len() {
            Ok(format!("{refused} malformed requests refused"))
        } else {
            Err(format!(
                "{} malformed requests accepted",
                lines.len() - refused
            ))
        }
    }

    fn run_trial(&mut self, fault: Fault) -> Result<(), String> {
        self.check_unprompted()?;
        let instance = self.instances.len() - 1;
        let at_s = self.start.elapsed().as_secs_f64();
        let mut trial = Trial {
            fault,
            instance,
            at_s,
            reached: None,
            recovered: false,
            periods_to_safe: None,
            note: String::new(),
        };
        let (cause, cure) = fault.injections();
        let injected = Instant::now();
        match fault {
            Fault::SocketAbuse => match self.abuse_socket() {
                Ok(note) => trial.note = note,
                Err(e) => trial.note = e,
            },
            Fault::Hangup => {
                // The standard library sends no signal but SIGKILL: the kill command does.
                let pid = self.instances[instance].child.id();
                let ok = Command::new("kill")
                    .args(["-HUP", &pid.to_string()])
                    .status()
                    .is_ok_and(|s| s.success());
                trial.note = if ok {
                    "sent".into()
                } else {
                    "kill -HUP failed".into()
                };
            }
            _ => {
                if let Some(cause) = &cause {
                    self.sim_fault(cause)?;
                }
            }
        }
        if fault == Fault::VisionStall {
            // The relief goes stale (forces fade to the free-space field) without a safe
            // state, and comes back when the thread publishes again.
            self.sim_fault("vision-stall")?;
            trial.reached = self
                .wait_status(Duration::from_secs(8), |s| s.surface_stale)
                .map(|s| {
                    (
                        format!("stale, {}", s.safety),
                        injected.elapsed().as_secs_f64(),
                    )
                });
            self.sim_fault("vision-resume")?;
            trial.recovered = trial
                .reached
                .as_ref()
                .is_some_and(|r| r.0 == "stale, normal")
                && self
                    .wait_status(Duration::from_secs(8), |s| {
                        !s.surface_stale && s.safety == "normal"
                    })
                    .is_some();
            self.trials.push(trial);
            return Ok(());
        }
        match fault.expected() {
            Some(reasons) => {
                trial.reached = self
                    .wait_status(Duration::from_secs(5), |s| {
                        reasons.contains(&s.safety.as_str())
                    })
                    .map(|s| (s.safety, injected.elapsed().as_secs_f64()));
            }
            None => {
                // The service carries on: still running, rendering, in the normal state.
                std::thread::sleep(Duration::from_millis(300));
                let alive = self.instances[instance]
                    .child
                    .try_wait()
                    .is_ok_and(|s| s.is_none());
                let normal = self.status().is_some_and(|s| s.safety == "normal");
                trial.recovered = alive && normal;
                if !trial.recovered {
                    trial.note = format!("{}; alive {alive}, normal {normal}", trial.note);
                }
            }
        }
        if fault.expected().is_some() {
            if let Some(cure) = &cure {
                self.sim_fault(cure)?;
            }
            if fault.powers_off() {
                let stopped = self.stop_instance();
                let started = stopped.and_then(|()| self.start_instance());
                trial.recovered = started.is_ok();
                if let Err(e) = started {
                    trial.note = e;
                }
            } else {
                std::thread::sleep(Duration::from_millis(100));
                let _ = request(&self.socket, &Request::ResetFaults, Duration::from_secs(2));
                trial.recovered = self
                    .wait_status(Duration::from_secs(5), |s| s.safety == "normal")
                    .is_some();
            }
        }
        self.trials.push(trial);
        Ok(())
    }
}

/// The log of instance `n`.
fn instance_log(dir: &Path, n: usize) -> Option<PathBuf> {
    std::fs::read_dir(dir.join(format!("logs-{n}")))
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .find(|p| p.extension().is_some_and(|x| x == "vlog"))
}

/// The `dropped=N` the service reported when it closed its log.
fn reported_drops(stderr: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(stderr).ok()?;
    let line = text
        .lines()
        .rev()
        .find(|l| l.contains("telemetry log closed"))?;
    let at = line.find("dropped")?;
    line[at..]
        .trim_start_matches(|c: char| !c.is_ascii_digit())
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

/// Periods from the first period showing `fault` (at or after `from`) to the first in a safe
/// state.
fn periods_to_safe(log: &Log, fault: Fault, from: usize) -> Option<(usize, u64)> {
    let seen = (from..log.records.len()).find(|&k| fault.visible_in(&log.records[k]))?;
    let safe = (seen..log.records.len()).find(|&k| log.records[k].safety.reason().is_some())?;
    Some((safe, log.records[safe].cycle - log.records[seen].cycle))
}

/// Run `videt soak`.
pub fn run(args: &SoakArgs) -> ToolResult {
    if !(args.duration.is_finite() && args.duration > 0.0) {
        return Err(format!("--duration must be positive seconds, got {}", args.duration).into());
    }
    if !(args.fault_every.is_finite() && args.fault_every >= 1.0) {
        return Err(format!(
            "--fault-every must be at least 1 s, got {}",
            args.fault_every
        )
        .into());
    }
    let dir = match &args.dir {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!(
            "videt-soak-{}-{}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_secs())
        )),
    };
    std::fs::create_dir_all(&dir)?;
    let videtd = match &args.videtd {
        Some(p) => p.clone(),
        None => std::env::current_exe()?.with_file_name("videtd"),
    };
    let mut soak = Soak {
        sim: args.sim.clone(),
        scene: args.scene.clone(),
        socket: dir.join("videtd.sock"),
        dir: dir.clone(),
        videtd,
        start: Instant::now(),
        instances: Vec::new(),
        trials: Vec::new(),
        unprompted: Vec::new(),
        stolen: StolenTime::start(),
    };
    eprintln!(
        "soak: {} s on the {} twin, output in {}",
        args.duration,
        args.sim,
        dir.display()
    );
    soak.start_instance()?;
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let mut last_power_off = Instant::now();
    let mut next_fault = Instant::now() + Duration::from_secs_f64(args.fault_every);
    let mut last_sample = Instant::now() - Duration::from_secs(10);
    let can = args.sim == "can";
    while soak.start.elapsed().as_secs_f64() < args.duration {
        if last_sample.elapsed() >= Duration::from_secs(2) {
            soak.sample();
            last_sample = Instant::now();
        }
        if Instant::now() < next_fault {
            std::thread::sleep(Duration::from_millis(50));
            continue;
        }
        let wire = rng.random_range(0..3u8);
        let power_off_allowed = last_power_off.elapsed().as_secs_f64() >= args.power_off_every;
        let mut choices = vec![Fault::SensorLoss(wire), Fault::SocketAbuse, Fault::Hangup];
        if args.scene == "box" {
            choices.push(Fault::VisionStall);
        }
        let harmless = choices.len();
        if power_off_allowed {
            choices.extend([Fault::WireBreak(wire), Fault::EStop]);
            if can {
                choices.extend([Fault::Emcy(wire), Fault::HeartbeatLoss(wire), Fault::BusOff]);
            }
        }
        let fault = if power_off_allowed {
            // One power-off fault as soon as one is allowed.
            choices[harmless + rng.random_range(0..choices.len() - harmless)]
        } else {
            choices[rng.random_range(0..harmless)]
        };
        eprintln!(
            "soak: {:7.1} s  {}",
            soak.start.elapsed().as_secs_f64(),
            fault.name()
        );
        if fault.powers_off() {
            last_power_off = Instant::now();
        }
        soak.run_trial(fault)?;
        let gap = args.fault_every * (0.5 + rng.random::<f64>());
        next_fault = Instant::now() + Duration::from_secs_f64(gap);
    }
    soak.sample();
    soak.check_unprompted()?;
    soak.stop_instance()?;
    report(&soak)
}

/// A run's resources after 20 s of warm-up, over the first and the last third of its samples:
/// the median RSS and the fewest descriptors and threads. A client of the socket holds a
/// thread and a descriptor for a moment, so any sample can catch one or two more than the
/// service keeps; a leak raises the fewest too.
fn after_warm_up(samples: &[Sample]) -> Option<(Sample, Sample)> {
    let warm: Vec<Sample> = samples
        .iter()
        .filter(|s| s.age_s >= 20.0)
        .copied()
        .collect();
    if warm.len() < 6 {
        return None;
    }
    let third = warm.len() / 3;
    let window = |w: &[Sample]| {
        let mut rss: Vec<u64> = w.iter().map(|s| s.rss_kb).collect();
        rss.sort_unstable();
        Sample {
            age_s: w[w.len() - 1].age_s,
            rss_kb: rss[rss.len() / 2],
            fds: w.iter().map(|s| s.fds).min().unwrap_or(0),
            threads: w.iter().map(|s| s.threads).min().unwrap_or(0),
        }
    };
    Some((window(&warm[..third]), window(&warm[warm.len() - third..])))
}

/// Why a run's session log is not complete, if it is not: damaged, not closed by its end frame
/// (every run is stopped through the control socket), or with gaps other than the drops the
/// service reported (`reported`).
fn incomplete_log(log: &Log, gaps: u64, reported: Option<u64>) -> Option<String> {
    let mut why = Vec::new();
    if let Some(note) = log.damage_note() {
        why.push(note);
    }
    if !log.closed() {
        why.push(log.end_note());
    }
    if reported != Some(gaps) {
        why.push(format!("log gaps {gaps}, reported dropped {reported:?}"));
    }
    (!why.is_empty()).then(|| why.join("; "))
}

fn report(soak: &Soak) -> ToolResult {
    let mut failures = Vec::new();
    // Session logs: complete (whole, closed, no unreported gap), replayable; periods to the
    // safe state.
    let mut trials = soak.trials.clone();
    let mut log_rows = Vec::new();
    let mut entries: Vec<Vec<SafeStateEntry>> = Vec::new();
    for (n, inst) in soak.instances.iter().enumerate() {
        let Some(path) = instance_log(&soak.dir, n) else {
            failures.push(format!("instance {n}: no session log"));
            entries.push(Vec::new());
            continue;
        };
        let log = read_log(&path)?;
        let gaps: u64 = log
            .records
            .windows(2)
            .map(|w| w[1].cycle.saturating_sub(w[0].cycle.saturating_add(1)))
            .sum();
        let reported = reported_drops(&inst.stderr);
        if let Some(why) = incomplete_log(&log, gaps, reported) {
            failures.push(format!("instance {n}: {why}"));
        }
        let replay = crate::replay::replay(&log, &Default::default())?;
        if !replay.identical() {
            failures.push(format!(
                "instance {n}: replay diverges: {:?}",
                replay.first_divergence
            ));
        }
        // What the finger felt: never beyond the felt bound, whatever the faults.
        let config = match &log.session {
            Some(Ok(session)) => session.config.clone(),
            _ => videt_config::Config::default(),
        };
        match crate::felt::felt_report(&log, &config, log.records.iter().enumerate()) {
            Ok(felt) => {
                println!("instance {n}: felt force: {felt}");
                if felt.over_bound > 0 {
                    failures.push(format!("instance {n}: felt force: {felt}"));
                }
            }
            Err(e) => failures.push(format!("instance {n}: felt force: {e}")),
        }
        let text = std::fs::read_to_string(&inst.stderr).unwrap_or_default();
        if text.contains("panicked") {
            failures.push(format!(
                "instance {n}: a panic in {}",
                inst.stderr.display()
            ));
        }
        let mut from = 0;
        for t in trials.iter_mut().filter(|t| t.instance == n) {
            if t.fault.expected().is_some() {
                if let Some((safe, periods)) = periods_to_safe(&log, t.fault, from) {
                    // A broken wire has no symptom before the supervisor's own inference: its
                    // detection time is the status column's.
                    t.periods_to_safe =
                        (!matches!(t.fault, Fault::WireBreak(_))).then_some(periods);
                    from = safe + 1;
                    // A sensor fault clears; look for the next fault after it.
                    while from < log.records.len() && log.records[from].safety.reason().is_some() {
                        from += 1;
                    }
                }
            }
        }
        entries.push(safe_state_entries(&log, &|cpu, from, to| {
            soak.stolen.stolen_ms(cpu, from, to)
        }));
        log_rows.push((n, log.records.len(), gaps, reported, replay.identical()));
    }
    println!("faults:");
    println!(
        "  {:>8}  {:<15} {:>4}  {:<16} {:>9}  {:>9}  {:<9}  note",
        "t, s", "fault", "run", "safe state", "after, ms", "periods", "recovered"
    );
    let mut by_kind: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    for t in &trials {
        let (state, ms) = t
            .reached
            .as_ref()
            .map_or(("-".to_string(), "-".to_string()), |(s, after)| {
                (s.clone(), format!("{:.0}", after * 1e3))
            });
        let periods = t.periods_to_safe.map_or("-".into(), |p| p.to_string());
        println!(
            "  {:>8.1}  {:<15} {:>4}  {:<16} {:>9}  {:>9}  {:<9}  {}",
            t.at_s,
            t.fault.name(),
            t.instance,
            state,
            ms,
            periods,
            if t.recovered { "yes" } else { "NO" },
            t.note
        );
        let mut ok = t.recovered;
        if t.fault == Fault::VisionStall {
            ok &= t.reached.is_some();
        }
        if t.fault.expected().is_some() {
            ok &= t.reached.is_some();
            // Within two periods of the fault being visible to the cycle (a broken wire is
            // inferred by the supervisor itself: no bound on its detection here).
            if !matches!(t.fault, Fault::WireBreak(_)) {
                ok &= t.periods_to_safe.is_some_and(|p| p <= 2);
            }
        }
        let e = by_kind.entry(t.fault.name()).or_default();
        e.0 += 1;
        e.1 += usize::from(ok);
        if !ok {
            failures.push(format!("{} at {:.1} s", t.fault.name(), t.at_s));
        }
    }
    let mut host_stall_count = 0;
    for u in &soak.unprompted {
        let (at, run, state) = (u.at_s, u.run, &u.state);
        // The run's last entry into this safe state before the soak found it (the log's clock
        // starts with the control loop, just after the run).
        let entry = entries.get(run).and_then(|e| {
            e.iter()
                .rfind(|x| x.state == *state && x.time_s <= u.run_s + 1.0)
        });
        match entry.and_then(|e| e.host) {
            Some(stall) => {
                host_stall_count += 1;
                println!(
                    "  {at:>8.1}  {:<15} {run:>4}  {state:<16}  (nobody injected it: {})",
                    "HOST STALL",
                    stall.describe()
                );
            }
            None => {
                println!(
                    "  {at:>8.1}  {:<15} {run:>4}  {state:<16}  (nobody injected it)",
                    "UNPROMPTED"
                );
                failures.push(format!(
                    "an unprompted {state} in run {run} before {at:.1} s"
                ));
            }
        }
    }
    if host_stall_count > 0 {
        println!(
            "host stalls: {host_stall_count} (safe states nobody injected, entered while the host kernel woke the control thread at least half a period late, or held a cycle up while the hypervisor took the CPU; the service's response is the documented one; not counted as failures)"
        );
    }
    println!("summary by fault (passed / injected):");
    for (name, (n, ok)) in &by_kind {
        println!("  {name:<15} {ok} / {n}");
    }
    println!("service runs:");
    println!(
        "  {:>3}  {:>8}  {:>8}  {:>6}  {:>9}  {:>15}  {:>9}  {:>9}  replay",
        "run", "life, s", "records", "gaps", "reported", "RSS, kB", "fds", "threads"
    );
    for (k, inst) in soak.instances.iter().enumerate() {
        let life = inst.samples.last().map_or(0.0, |s| s.age_s);
        let row = log_rows.iter().find(|r| r.0 == k);
        let fmt2 = |a: String, b: String| format!("{a} -> {b}");
        let (rss, fds, threads) = match after_warm_up(&inst.samples) {
            Some((a, b)) => {
                // Flat: no more than 2 MB of RSS growth after warm-up, no more descriptors or
                // threads at the end than at the start.
                if b.rss_kb > a.rss_kb + 2048 || b.fds > a.fds || b.threads > a.threads {
                    failures.push(format!(
                        "run {k}: RSS {} -> {} kB, fds {} -> {}, threads {} -> {}",
                        a.rss_kb, b.rss_kb, a.fds, b.fds, a.threads, b.threads
                    ));
                }
                (
                    fmt2(a.rss_kb.to_string(), b.rss_kb.to_string()),
                    fmt2(a.fds.to_string(), b.fds.to_string()),
                    fmt2(a.threads.to_string(), b.threads.to_string()),
                )
            }
            None => ("(short)".into(), "-".into(), "-".into()),
        };
        println!(
            "  {:>3}  {:>8.0}  {:>8}  {:>6}  {:>9}  {:>15}  {:>9}  {:>9}  {}",
            k,
            life,
            row.map_or(0, |r| r.1),
            row.map_or(0, |r| r.2),
            row.and_then(|r| r.3).map_or("-".into(), |d| d.to_string()),
            rss,
            fds,
            threads,
            match row.map(|r| r.4) {
                Some(true) => "identical",
                Some(false) => "DIVERGES",
                None => "-",
            }
        );
    }
    if failures.is_empty() {
        println!(
            "soak: PASSED ({} faults, {} service runs)",
            trials.len(),
            soak.instances.len()
        );
        Ok(ExitCode::SUCCESS)
    } else {
        for f in &failures {
            println!("  FAILED: {f}");
        }
        println!("soak: FAILED");
        Ok(ExitCode::FAILURE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(fds: impl Fn(usize) -> usize, rss_kb: impl Fn(usize) -> u64) -> Vec<Sample> {
        (0..60)
            .map(|k| Sample {
                age_s: 20.0 + 2.0 * k as f64,
                rss_kb: rss_kb(k),
                fds: fds(k),
                threads: 7 + usize::from(fds(k) > 8),
            })
            .collect()
    }

    #[test]
    fn a_session_log_is_complete_only_when_whole_closed_and_without_unreported_gaps() {
        use videt_runtime::telemetry::{EndReason, LogHeader, SessionEnd};
        let header = LogHeader {
            rate_hz: 1000,
            start_unix_ns: 0,
        };
        let records = (0..5)
            .map(|cycle| CycleRecord {
                cycle,
                ..CycleRecord::default()
            })
            .collect();
        let mut log = Log::of_records(header, records);
        // Ended without closing: a service killed, or its log cut on a record boundary.
        let why = incomplete_log(&log, 0, Some(0)).unwrap();
        assert!(why.contains("ended without closing, at cycle 4"), "{why}");
        log.end = Some(SessionEnd {
            reason: EndReason::StopRequest,
            last_cycle: Some(4),
            periods: 5,
            dropped: 0,
        });
        assert_eq!(incomplete_log(&log, 0, Some(0)), None);
        let why = incomplete_log(&log, 2, Some(0)).unwrap();
        assert!(
            why.contains("log gaps 2, reported dropped Some(0)"),
            "{why}"
        );
        log.damage = Some(videt_runtime::telemetry::Damage {
            offset: 100,
            what: "an incomplete frame".into(),
        });
        assert!(incomplete_log(&log, 0, Some(0))
            .unwrap()
            .contains("the rest is damaged"));
    }

    #[test]
    fn passing_socket_clients_are_not_a_leak_but_a_growing_baseline_is() {
        // A client's descriptor (and thread) caught now and then, more often near the end.
        let (a, b) = after_warm_up(&samples(
            |k| 8 + 2 * usize::from(k % 7 == 3 || k > 55),
            |_| 31_632,
        ))
        .unwrap();
        assert_eq!((a.fds, b.fds, a.threads, b.threads), (8, 8, 7, 7));
        // One descriptor kept every 10 samples: the fewest grows.
        let (a, b) = after_warm_up(&samples(|k| 8 + k / 10, |_| 31_632)).unwrap();
        assert!(b.fds > a.fds, "{} -> {}", a.fds, b.fds);
        // RSS: the median of each third.
        let (a, b) = after_warm_up(&samples(|_| 8, |k| 30_000 + 100 * k as u64)).unwrap();
        assert!(b.rss_kb >= a.rss_kb + 4000, "{} -> {}", a.rss_kb, b.rss_kb);
        assert!(after_warm_up(&samples(|_| 8, |_| 1)[..5]).is_none());
    }
}
