//! The technician-facing flows: auto-initialization and wire replacement, with the manual steps
//! asked of a [`Technician`] (a person at a terminal, or the twin's simulated one).
//!
//! Nothing here writes the calibration: a flow returns the new [`Calibration`] and the caller
//! saves it, so every failure leaves the previous calibration untouched.

use std::sync::atomic::AtomicBool;
use std::time::{SystemTime, UNIX_EPOCH};
use videt_runtime::WIREMAN_WIRES;

use videt_config::calibration::{utc_timestamp, Calibration, WorkspaceRecord, FORMAT_VERSION};
use videt_config::Config;
use videt_control::autoinit::{
    workspace, BaseTriangle, Failure, Plan, Procedure, Stage, Status, Workspace,
};
use videt_hal::Lifecycle;

use super::params::{procedure_params, workspace_spec};
use super::runner::{InitHardware, Readings, RunSettings, Runner};
use videt_runtime::control_loop::{start_hardware, StartError};
use videt_runtime::setup;

/// A manual step the procedure needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// Pull the three wires out and connect them to the empty thimble; hands off afterwards.
    ConnectWires,
    /// Wire `wire` is released: take the old yarn off and fit the new one; leave its end free.
    FitNewWire {
        /// The wire.
        wire: usize,
    },
    /// Pull the (homed, detached) wire out as far as it goes, hold it, then let it wind back.
    PullOutWire {
        /// The wire.
        wire: usize,
    },
}

impl Request {
    /// A short, stable name (`connect-wires`, `fit-new-wire`, `pull-out-wire`).
    pub fn name(self) -> &'static str {
        match self {
            Request::ConnectWires => "connect-wires",
            Request::FitNewWire { .. } => "fit-new-wire",
            Request::PullOutWire { .. } => "pull-out-wire",
        }
    }

    /// The wire the step is about, if one.
    pub fn wire(self) -> Option<usize> {
        match self {
            Request::ConnectWires => None,
            Request::FitNewWire { wire } | Request::PullOutWire { wire } => Some(wire),
        }
    }

    /// The wire left without torque while the step is done (free to be pulled).
    pub fn released_wire(self) -> Option<usize> {
        match self {
            Request::FitNewWire { wire } => Some(wire),
            _ => None,
        }
    }

    /// What the technician is asked to do, in words.
    pub fn instructions(self) -> String {
        match self {
            Request::ConnectWires => "pull the three wires out, connect their ends to the empty thimble's terminal, let go and keep hands off; press Enter".into(),
            Request::FitNewWire { wire } => format!("wire {wire} is released: take the old yarn off, knot the new one on the pulley, route it over the idle pulley and through ring {wire}, fit its end sphere and leave the end free; press Enter"),
            Request::PullOutWire { wire } => format!("pull wire {wire} out as far as it goes (to its knot), then let it go back slowly; press Enter"),
        }
    }
}

/// Who performs the manual steps. `runner.hold_until` keeps the wires at the pay-out tension
/// while waiting (a released wire free).
pub trait Technician<H: InitHardware> {
    /// Perform `request` and return once it is done.
    fn perform(
        &mut self,
        request: Request,
        hw: &mut H,
        runner: &mut Runner,
        stop: &AtomicBool,
    ) -> Result<(), Failure>;
    /// A progress message (stage changes, results).
    fn inform(&mut self, message: &str);
    /// The procedure entered `stage` with these readings (called before the stage's message).
    fn stage(&mut self, _stage: Stage, _readings: &Readings) {}
}

/// Why a flow failed. Each kind has its own exit code.
#[derive(Debug, thiserror::Error)]
pub enum InitError {
    /// The procedure ended with a failure.
    #[error("{0}")]
    Procedure(Failure),
    /// The new wire is shorter than the workspace needs.
    #[error("wire {wire}: usable length {usable_m:.3} m is shorter than the {required_m:.3} m the workspace needs (with margin); fit a longer yarn")]
    WireTooShort {
        /// The wire.
        wire: usize,
        /// Its usable length, metres.
        usable_m: f64,
        /// What the workspace needs, metres.
        required_m: f64,
    },
    /// The hardware would not start.
    #[error("{0}")]
    Start(#[from] StartError),
    /// The wire's end did not come back to the same stop: the yarn slips on the pulley or its
    /// end is not held by the ring.
    #[error("wire {wire}: homed twice, its stop moved by {:.2} mm; check the yarn's knot on the pulley and its end sphere", shift_m * 1e3)]
    HomeNotRepeatable {
        /// The wire.
        wire: usize,
        /// How far the stop moved, metres.
        shift_m: f64,
    },
    /// A wire number out of range.
    #[error("wire {0} does not exist: wires are 0, 1, 2")]
    NoSuchWire(usize),
    /// The measured calibration cannot be used by the control cycle.
    #[error("the measured calibration cannot be used: {0}")]
    Unusable(String),
}

impl InitError {
    /// The process exit code for this error (documented in `videt init --help`).
    pub fn exit_code(&self) -> u8 {
        match self {
            InitError::Procedure(f) => failure_exit_code(f),
            InitError::WireTooShort { .. } => 21,
            InitError::Start(_) => 22,
            InitError::HomeNotRepeatable { .. } => 25,
            InitError::NoSuchWire(_) => 2,
            InitError::Unusable(_) => 16,
        }
    }
    /// A short, stable name.
    pub fn name(&self) -> &'static str {
        match self {
            InitError::Procedure(f) => f.name(),
            InitError::WireTooShort { .. } => "wire-too-short",
            InitError::Start(_) => "hardware-start",
            InitError::HomeNotRepeatable { .. } => "home-not-repeatable",
            InitError::NoSuchWire(_) => "no-such-wire",
            InitError::Unusable(_) => "unusable-calibration",
        }
    }
}

/// The message a failed flow ends with: what went wrong, and that nothing was lost.
pub fn failure_message(e: &InitError, calibration_path: &std::path::Path) -> String {
    format!(
        "{e}; the procedure ended with the motors at minimum tension and the previous calibration ({}) is unchanged",
        calibration_path.display()
    )
}

/// Exit code of each procedure failure.
pub fn failure_exit_code(f: &Failure) -> u8 {
    match f {
        Failure::EmergencyStop => 10,
        Failure::LimitHit { .. } => 11,
        Failure::NotConnected { .. } => 12,
        Failure::TensionNeverRose { .. } => 13,
        Failure::SidesDisagree { .. } => 14,
        Failure::TriangleInequality { .. } => 15,
        Failure::DegenerateTriangle { .. } => 16,
        Failure::DriveFault { .. } => 17,
        Failure::SensorFault => 18,
        Failure::Timeout { .. } => 19,
        Failure::Cancelled => 20,
    }
}

/// A successful auto-initialization.
#[derive(Debug, Clone)]
pub struct InitOutcome {
    /// The measured triangle.
    pub triangle: BaseTriangle,
    /// Encoder counts at free length zero.
    pub zero_counts: [i64; WIREMAN_WIRES],
    /// The workspace.
    pub workspace: Workspace,
    /// The calibration to save.
    pub calibration: Calibration,
}

/// The run settings of a configuration.
pub fn run_settings(config: &Config) -> RunSettings {
    RunSettings {
        rate_hz: config.control.rate_hz,
        transmission: setup::transmission(config),
        pay_out_tension_n: config.autoinit.pay_out_tension_n,
        hold_after_s: 0.3,
        governor_speed_m_s: config.autoinit.wind_speed_m_s,
    }
}

fn stage_message(stage: Stage, r: &Readings) -> Option<String> {
    let t = r.tension_n;
    match stage {
        Stage::Settle => Some("tensioning the wires".into()),
        Stage::Homing => Some("homing: winding until each wire's end stops at its ring".into()),
        Stage::Winding(w) => Some(format!(
            "winding wire {w} until the thimble reaches ring {w} (tensions {:.2}, {:.2}, {:.2} N)",
            t[0], t[1], t[2]
        )),
        Stage::Finished | Stage::Failed => None,
    }
}

fn run_plan<H: InitHardware, T: Technician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    config: &Config,
    plan: Plan,
    stop: &AtomicBool,
) -> Result<Procedure, InitError> {
    let mut procedure = Procedure::new(procedure_params(config), plan);
    let status = runner.run(hw, &mut procedure, stop, &mut |stage, r| {
        tech.stage(stage, r);
        if let Some(m) = stage_message(stage, r) {
            tech.inform(&m);
        }
    });
    match status {
        Status::Failed(f) => Err(InitError::Procedure(f)),
        _ => Ok(procedure),
    }
}

/// What every flow needs besides the hardware and the technician.
#[derive(Debug, Clone, Copy)]
pub struct FlowContext<'a> {
    /// The configuration.
    pub config: &'a Config,
    /// Where the calibration is measured: `device` or `twin`.
    pub source: &'a str,
    /// Set to stop the flow (signals, an operator's stop).
    pub stop: &'a AtomicBool,
}

/// What the procedure measured on the hardware, before the (slow, pure) workspace computation.
#[derive(Debug, Clone, Copy)]
pub struct Measurement {
    /// The measured triangle.
    pub triangle: BaseTriangle,
    /// Encoder counts at free length zero.
    pub zero_counts: [i64; WIREMAN_WIRES],
    /// Encoder resolution the counts were taken with, metres per count.
    pub metres_per_count: f64,
}

impl Measurement {
    /// Wire length at encoder count zero, metres (the control cycle's encoder zeros).
    pub fn length_at_zero_m(&self) -> [f64; WIREMAN_WIRES] {
        videt_config::calibration::length_at_zero_m(&self.zero_counts, self.metres_per_count)
    }
}

/// Auto-initialize on the hardware: ask for the wires to be connected to the empty thimble, wind
/// each in turn, solve the base triangle. The hardware must be started (see [`start`]).
pub fn measure<H: InitHardware, T: Technician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    ctx: &FlowContext<'_>,
) -> Result<Measurement, InitError> {
    let (config, stop) = (ctx.config, ctx.stop);
    tech.perform(Request::ConnectWires, hw, runner, stop)
        .map_err(InitError::Procedure)?;
    let procedure = run_plan(hw, tech, runner, config, Plan::Initialize, stop)?;
    let triangle = *procedure
        .result()
        .ok_or(InitError::Procedure(Failure::Cancelled))?;
    Ok(Measurement {
        triangle,
        zero_counts: procedure.homed_zero_counts(),
        metres_per_count: runner.settings().transmission.metres_per_count(),
    })
}

/// The workspace the measured rig serves and the calibration record to save (pure; the
/// workspace is a grid search: keep it off a thread that must talk to the drives every period).
pub fn outcome(config: &Config, source: &str, m: &Measurement) -> InitOutcome {
    let triangle = m.triangle;
    let spec = workspace_spec(config);
    let ws = workspace(&triangle.rig, &spec);
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let g = triangle.rig.guides_m();
    let calibration = Calibration {
        format: FORMAT_VERSION,
        created_unix_s: now,
        created_utc: utc_timestamp(now),
        source: source.to_string(),
        sides_m: triangle.sides_m,
        residuals_m: triangle.residuals_m,
        guides_m: core::array::from_fn(|i| [g[i].x, g[i].y, g[i].z]),
        wire_zero_counts: m.zero_counts,
        metres_per_count: m.metres_per_count,
        workspace: WorkspaceRecord {
            force_n: spec.force_n,
            max_condition: spec.max_condition,
            volume_m3: ws.volume_m3,
            min_m: ws.min_m,
            max_m: ws.max_m,
            required_length_m: ws.required_length_m,
        },
    };
    InitOutcome {
        triangle,
        zero_counts: m.zero_counts,
        workspace: ws,
        calibration,
    }
}

/// Auto-initialize ([`measure`]) and compute the calibration ([`outcome`]).
pub fn initialize<H: InitHardware, T: Technician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    ctx: &FlowContext<'_>,
) -> Result<InitOutcome, InitError> {
    measure(hw, tech, runner, ctx).map(|m| outcome(ctx.config, ctx.source, &m))
}

/// Replace wire `wire` ([`replace_wire_measure`]) and compute the calibration ([`outcome`]).
pub fn replace_wire<H: InitHardware, T: Technician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    ctx: &FlowContext<'_>,
    wire: usize,
    required_length_m: f64,
) -> Result<InitOutcome, InitError> {
    replace_wire_measure(hw, tech, runner, ctx, wire, required_length_m)
        .map(|m| outcome(ctx.config, ctx.source, &m))
}

/// Replace wire `wire`: release it while the new yarn is fitted, home it (its tension must rise
/// at the ring), check its usable length against `required_length_m`, then auto-initialize
/// ([`measure`]).
pub fn replace_wire_measure<H: InitHardware, T: Technician<H>>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    ctx: &FlowContext<'_>,
    wire: usize,
    required_length_m: f64,
) -> Result<Measurement, InitError> {
    let (config, stop) = (ctx.config, ctx.stop);
    if wire >= WIREMAN_WIRES {
        return Err(InitError::NoSuchWire(wire));
    }
    tech.inform(&format!("wire {wire} released: it turns freely"));
    tech.perform(Request::FitNewWire { wire }, hw, runner, stop)
        .map_err(InitError::Procedure)?;
    let mut wires = [false; WIREMAN_WIRES];
    wires[wire] = true;
    let homing = run_plan(hw, tech, runner, config, Plan::Home { wires }, stop)?;
    let zero = homing.homed_zero_counts()[wire];
    tech.inform(&format!("wire {wire} homed: its end stops at the ring"));

    // Usable length: pulled out as far as it goes, measured from the new zero; then it is
    // wound back to its ring by homing it again (speed-limited), which checks the zero too.
    runner.reset_lowest_counts();
    tech.perform(Request::PullOutWire { wire }, hw, runner, stop)
        .map_err(InitError::Procedure)?;
    let mpc = runner.settings().transmission.metres_per_count();
    let rehome = run_plan(hw, tech, runner, config, Plan::Home { wires }, stop)?;
    let longest_m = (zero - runner.lowest_counts()[wire]) as f64 * mpc;
    let zero_shift_m = (rehome.homed_zero_counts()[wire] - zero) as f64 * mpc;
    if zero_shift_m.abs() > config.autoinit.side_tolerance_m {
        return Err(InitError::HomeNotRepeatable {
            wire,
            shift_m: zero_shift_m,
        });
    }
    tech.inform(&format!(
        "wire {wire}: usable length {:.3} m (the workspace needs {:.3} m)",
        longest_m, required_length_m
    ));
    if longest_m < required_length_m {
        return Err(InitError::WireTooShort {
            wire,
            usable_m: longest_m,
            required_m: required_length_m,
        });
    }
    measure(hw, tech, runner, ctx)
}

/// The length every wire must be usable for: the workspace's longest wire plus the margin,
/// from the current calibration when there is one, else from the configured guides.
pub fn required_wire_length_m(config: &Config, current: Option<&Calibration>) -> f64 {
    let longest = match current {
        Some(c) => c
            .workspace
            .required_length_m
            .iter()
            .fold(0.0_f64, |a, b| a.max(*b)),
        None => match setup::rig(config) {
            Ok(rig) => workspace(&rig, &workspace_spec(config))
                .required_length_m
                .iter()
                .fold(0.0_f64, |a, b| a.max(*b)),
            Err(_) => config.autoinit.max_length_m,
        },
    };
    longest + config.autoinit.wire_length_margin_m
}

/// Bring the hardware up for the procedure (configure, activate, enable).
pub fn start<H: InitHardware + Lifecycle>(hw: &mut H) -> Result<(), InitError> {
    start_hardware(hw).map_err(InitError::Start)
}
