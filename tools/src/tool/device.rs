//! What the motor-driving subcommands (`init`, `wire replace`, `tension-calibrate`) share: where
//! the configuration, the calibration and the motors lock are, the twin's rehearsal options,
//! the technician at the terminal, and the exit codes.

use std::io::{BufRead, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use clap::Args;
use videt_config::Config;
use videt_control::autoinit::Failure;

use videt_service::init::commission::{CommissionStep, CommissionTechnician};
use videt_service::init::runner::{InitHardware, Runner};
use videt_service::init::session::{Request, Technician};
use videt_service::init::tension::{TensionStep, TensionTechnician};
use videt_service::init::twin::{parse_fault, parse_guides, TwinSetup};
use videt_service::init::{LockError, MotorsLock};
use videt_service::socket::{request, Request as SocketRequest};

/// Where the configuration lives on the device.
pub const DEFAULT_CONFIG: &str = "/etc/videt/videt.toml";

/// Exit codes every motor-driving subcommand shares (the procedure's own failures are 10-25).
pub const EXIT_USAGE: u8 = 2;
/// The motors are held by another process (`videtd`, another `videt`).
pub const EXIT_MOTORS_BUSY: u8 = 23;
/// The calibration could not be written (the previous one is unchanged).
pub const EXIT_CALIBRATION_WRITE: u8 = 24;
/// No device backend is built in.
pub const EXIT_NO_BACKEND: u8 = 3;

/// The exit codes, for `--help`.
pub const EXIT_CODES_HELP: &str = "Exit codes: 0 done; 2 bad arguments or configuration; 3 no device backend on this system (use --sim); \
10 e-stop pressed; 11 a limit was hit (tension, speed, length); 12 a wire is not connected (never moved); \
13 a wire's tension never rose (broken or slipping); 14 the two measurements of a side disagree; \
15 the sides violate the triangle inequality; 16 the triangle is degenerate; 17 drive fault; \
18 tension-sensor fault; 19 timeout; 20 cancelled (or no terminal to prompt, without --yes); 21 new wire too short; \
22 the device could not be opened or would not start; \
23 the motors are in use by another process (or videtd runs another procedure); 24 the calibration \
could not be written; 25 a re-homed wire's stop moved; 26 the connection to videtd broke before the \
procedure ended. When videtd answers on its control socket the procedure runs in videtd, on its \
hardware, with the same messages and exit codes. On every failure the procedure ends with every motor at minimum \
tension (powered off after an e-stop or a drive fault) and the previous calibration untouched; the \
tool disables the drives when it exits.";

/// Options of the subcommands that drive the motors.
#[derive(Debug, Clone, Args)]
pub struct DeviceArgs {
    /// Rehearse on the digital twin instead of the device. The twin starts at rest (wires
    /// detached, fully wound) with arbitrary encoder offsets and noisy tension sensors; a simulated
    /// technician does the manual steps.
    #[arg(long)]
    pub sim: bool,
    /// The twin's true guide points, metres, in the frame plane: "X,Y;X,Y;X,Y"
    /// (default: the configured `rig.guides_m`).
    #[arg(
        long,
        value_name = "X,Y;X,Y;X,Y",
        requires = "sim",
        allow_hyphen_values = true
    )]
    pub sim_guides: Option<String>,
    /// Seed of the twin: encoder offsets, sensor noise, where the thimble is connected.
    #[arg(long, value_name = "N", default_value_t = 1, requires = "sim")]
    pub sim_seed: u64,
    /// A fault to rehearse on the twin (repeatable): disconnected:N, estop:SECS, break:N:SECS,
    /// detach:N:SECS, sensor:N:SECS, slip:N:MM:SECS (SECS after the wires are connected); or a
    /// wiring mistake the rig was built with: reversed-motor:N, reversed-encoder:N,
    /// swapped-nodes:A,B, inverted-cell:N, estop-level, swapped-cameras (the configuration's
    /// fixes apply to it as on the device).
    #[arg(long, value_name = "FAULT", requires = "sim")]
    pub sim_fault: Vec<String>,
    /// Configuration file (default: /etc/videt/videt.toml when present; with --sim, built-in
    /// defaults otherwise).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Calibration file (default: `files.calibration` of the configuration,
    /// /var/lib/videt/calibration.toml; with --sim: $XDG_STATE_HOME/videt/calibration-sim.toml,
    /// else ~/.local/state/videt/calibration-sim.toml).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Motors lock file (default: `files.motors_lock`, /run/videt/motors.lock; with --sim none
    /// unless given: the twin is private to this process).
    #[arg(long, value_name = "FILE")]
    pub lock: Option<PathBuf>,
    /// The running videtd's control socket (default: `socket.path` of the configuration; with
    /// --sim none unless given). When videtd answers on it, the procedure runs in videtd on its
    /// own hardware (forces ramped out first, rendering resumed afterwards with the new
    /// calibration); with --sim and --socket, the twin options (--sim-seed, --sim-fault, ...)
    /// go to videtd's twin.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<PathBuf>,
    /// Do not wait at the prompts: the manual steps are already done (scripts).
    #[arg(long)]
    pub yes: bool,
    /// Confirm each manual step with a line on stdin, a terminal or not (a script that does
    /// the steps as they are asked for; without it, stdin must be a terminal).
    #[arg(long, conflicts_with = "yes")]
    pub steps_from_stdin: bool,
    /// Print the result as JSON on stdout (progress stays on stderr).
    #[arg(long)]
    pub json: bool,
}

/// A subcommand's failure, with its exit code.
#[derive(Debug)]
pub struct Exit {
    /// Exit code.
    pub code: u8,
    /// Stable name (JSON `error`).
    pub name: std::borrow::Cow<'static, str>,
    /// Message.
    pub message: String,
}

impl Exit {
    /// An exit with a code, a name and a message.
    pub fn new(
        code: u8,
        name: impl Into<std::borrow::Cow<'static, str>>,
        message: impl Into<String>,
    ) -> Exit {
        Exit {
            code,
            name: name.into(),
            message: message.into(),
        }
    }

    /// Report it (stderr; with `json` also a JSON object on stdout) and give the exit code.
    pub fn report(&self, json: bool) -> std::process::ExitCode {
        eprintln!("videt: {}", self.message);
        if json {
            println!(
                "{}",
                serde_json::json!({"error": self.name, "message": self.message, "exit_code": self.code})
            );
        }
        std::process::ExitCode::from(self.code)
    }
}

use videt_service::init::daemon::sim_state_dir;

impl DeviceArgs {
    /// Load the configuration.
    pub fn load_config(&self) -> Result<Config, Exit> {
        let bad = |e: videt_config::ConfigError| Exit::new(EXIT_USAGE, "config", e.to_string());
        match &self.config {
            Some(path) => Config::load(path).map_err(bad),
            None if Path::new(DEFAULT_CONFIG).exists() => {
                Config::load(Path::new(DEFAULT_CONFIG)).map_err(bad)
            }
            None if self.sim => Ok(Config::default()),
            None => Err(Exit::new(
                EXIT_USAGE,
                "config",
                format!("no configuration: pass --config FILE or install {DEFAULT_CONFIG}"),
            )),
        }
    }

    /// The calibration file.
    pub fn calibration_path(&self, config: &Config) -> PathBuf {
        match &self.calibration {
            Some(p) => p.clone(),
            None if self.sim => sim_state_dir().join("calibration-sim.toml"),
            None => PathBuf::from(&config.files.calibration),
        }
    }

    /// The motors lock file; none with --sim unless --lock names one (a twin is private to its
    /// process: there are no shared motors).
    pub fn lock_path(&self, config: &Config) -> Option<PathBuf> {
        match &self.lock {
            Some(p) => Some(p.clone()),
            None if self.sim => None,
            None => Some(PathBuf::from(&config.files.motors_lock)),
        }
    }

    /// The running service's control socket, when there may be one.
    pub fn socket_path(&self, config: &Config) -> Option<PathBuf> {
        match &self.socket {
            Some(p) => Some(p.clone()),
            None if self.sim => None,
            None => Some(PathBuf::from(&config.socket.path)),
        }
    }

    /// Take the motors lock (see [`Self::lock_path`]) for a run on the hardware itself, or say
    /// who holds it.
    pub fn lock_motors(&self, config: &Config) -> Result<Option<MotorsLock>, Exit> {
        let Some(path) = self.lock_path(config) else {
            return Ok(None);
        };
        MotorsLock::acquire(&path).map(Some).map_err(|e| {
            let why = match (&e, self.socket_path(config)) {
                (LockError::Busy { .. }, Some(socket)) => format!(
                    "; the service's control socket {} does not answer",
                    socket.display()
                ),
                _ => String::new(),
            };
            Exit::new(EXIT_MOTORS_BUSY, "motors-busy", format!("{e}{why}"))
        })
    }

    /// The running service's control socket, when it answers: procedures then run on its
    /// hardware through it.
    pub fn running_service(&self, config: &Config) -> Option<PathBuf> {
        let socket = self.socket_path(config).filter(|s| s.exists())?;
        request(&socket, &SocketRequest::Status, Duration::from_secs(3))
            .is_ok_and(|r| r.ok)
            .then_some(socket)
    }

    /// The twin's set-up from the rehearsal options.
    pub fn twin_setup(&self, config: &Config) -> Result<TwinSetup, Exit> {
        let mut setup = TwinSetup::from_config(config, self.sim_seed);
        if let Some(g) = &self.sim_guides {
            setup.guides_m = parse_guides(g).map_err(|e| Exit::new(EXIT_USAGE, "usage", e))?;
        }
        for f in &self.sim_fault {
            setup.faults.push(
                parse_fault(f, &videt_runtime::setup::transmission(config))
                    .map_err(|e| Exit::new(EXIT_USAGE, "usage", e))?,
            );
        }
        Ok(setup)
    }

    /// The error for a device run: no backend is built into this `videt`.
    pub fn no_backend(&self) -> Exit {
        Exit::new(
            EXIT_NO_BACKEND,
            "no-backend",
            "no device backend is built into this videt: run with --sim to rehearse on the digital twin",
        )
    }
}

/// Ask a yes/no question on the terminal; anything but `y`/`yes` (or no terminal) is no.
pub fn confirm(question: &str) -> bool {
    if !std::io::stdin().is_terminal() {
        return false;
    }
    eprint!("videt: {question}");
    let mut line = String::new();
    std::io::stdin().lock().read_line(&mut line).is_ok()
        && matches!(line.trim().to_ascii_lowercase().as_str(), "y" | "yes")
}

/// A stop flag set by SIGINT and SIGTERM.
pub fn stop_on_signals() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        // Without the handler, a signal ends the process and the drives stop by themselves.
        let _ = signal_hook::flag::register(signal, Arc::clone(&stop));
    }
    stop
}

/// The technician at a terminal: prints each manual step and waits for Enter while the motors
/// hold the wires at the pay-out tension (a released wire turns freely). With `yes` it does
/// not wait; without a terminal it cancels, unless each step is to be confirmed by a line on
/// stdin (`steps_from_stdin`: a script that does the steps).
#[derive(Debug)]
pub struct TerminalTechnician {
    /// Do not wait.
    pub yes: bool,
    /// Each step is confirmed by a line on stdin, terminal or not.
    pub steps_from_stdin: bool,
    /// Told when Enter is pressed, during a tension-calibration step.
    enter: Option<std::sync::mpsc::Receiver<()>>,
}

impl TerminalTechnician {
    /// A technician at this terminal; with `yes` the steps are taken as done already; with
    /// `steps_from_stdin` each is confirmed by a line on stdin even when it is not a terminal.
    pub fn new(yes: bool, steps_from_stdin: bool) -> TerminalTechnician {
        TerminalTechnician {
            yes,
            steps_from_stdin,
            enter: None,
        }
    }

    /// Whether a step's confirmation can be waited for on stdin.
    fn can_wait(&self) -> bool {
        self.steps_from_stdin || std::io::stdin().is_terminal()
    }
}

impl<H: InitHardware> Technician<H> for TerminalTechnician {
    fn perform(
        &mut self,
        request: Request,
        hw: &mut H,
        runner: &mut Runner,
        stop: &AtomicBool,
    ) -> Result<(), Failure> {
        eprintln!("videt: {}", request.instructions());
        if self.yes {
            return Ok(());
        }
        if !self.can_wait() {
            return Err(Failure::Cancelled);
        }
        let rx = enter_pressed();
        runner.hold_until(
            hw,
            request.released_wire(),
            stop,
            &mut || rx.try_recv().is_ok(),
            &mut |_| {},
        )
    }

    fn inform(&mut self, message: &str) {
        eprintln!("videt: {message}");
    }
}

impl TerminalTechnician {
    /// Tell the technician `instructions`, and from now on watch for the Enter that says they
    /// are done (with `yes`: done already). Without a terminal to prompt: cancelled.
    fn prompt(&mut self, instructions: &str) -> Result<(), Failure> {
        eprintln!("videt: {instructions}");
        self.enter = None;
        if self.yes {
            return Ok(());
        }
        if !self.can_wait() {
            return Err(Failure::Cancelled);
        }
        self.enter = Some(enter_pressed());
        Ok(())
    }

    /// Whether the technician said the prompted step is done.
    fn entered(&mut self) -> bool {
        self.enter.as_ref().is_none_or(|rx| rx.try_recv().is_ok())
    }
}

impl<H: InitHardware> TensionTechnician<H> for TerminalTechnician {
    fn perform(&mut self, step: TensionStep, _hw: &mut H) -> Result<(), Failure> {
        self.prompt(&step.instructions())
    }

    fn step_done(&mut self, _step: TensionStep, _hw: &mut H) -> bool {
        self.entered()
    }
}

impl<H: InitHardware> CommissionTechnician<H> for TerminalTechnician {
    fn perform_commission(&mut self, step: CommissionStep, _hw: &mut H) -> Result<(), Failure> {
        self.prompt(&step.instructions())
    }

    fn commission_step_done(&mut self, _step: CommissionStep, _hw: &mut H) -> bool {
        self.entered()
    }
}

/// A receiver that gets one message when the technician presses Enter (stdin is read on its own
/// thread, so the caller keeps its period).
pub(crate) fn enter_pressed() -> std::sync::mpsc::Receiver<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let mut line = String::new();
        let _ = std::io::stdin().lock().read_line(&mut line);
        let _ = tx.send(());
    });
    rx
}
