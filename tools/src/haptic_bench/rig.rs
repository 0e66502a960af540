//! One experiment of the haptic bench: the real control cycle and loop driving the twin through
//! the CiA 402 driver and simulated drives (per-mille torque, the RPDO taking effect at the next
//! SYNC), its strain gauges on the configured converter's timing, on the twin's simulated
//! clock (deterministic, faster than real time). The twin's physics is the truth the bench
//! measures against: the force the wires put on the thimble, where the thimble is.

use std::sync::atomic::AtomicBool;
use videt_runtime::WIREMAN_WIRES;

use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::surface::Plane;
use videt_control::{ControlStep, FeltTally, Rig3};
use videt_hal::{
    AngleSensors, Clock, DriveSample, EStop, ErrorType, Lifecycle, LifecycleState, MonoTime,
    TensionSensors, WireDrives,
};
use videt_sim::{Vec3, VirtualOperator};

use videt_assembly::can_twin::{drive_config, CanTwin};
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopSettings, LoopStats,
    WindowStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::FixedSurface;

/// The twin's state at the end of one control period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthSample {
    /// Simulated time, seconds since the experiment started.
    pub time_s: f64,
    /// Thimble position, metres.
    pub position_m: Vec3,
    /// Thimble velocity, m/s.
    pub velocity_m_s: Vec3,
    /// Resultant force of the wires on the thimble, newtons.
    pub wire_force_n: Vec3,
    /// The operator's hand force on the thimble, newtons.
    pub hand_force_n: Vec3,
    /// Largest wire tension, newtons.
    pub max_tension_n: f64,
    /// Every wire's tension, newtons.
    pub tension_n: [f64; WIREMAN_WIRES],
    /// Every wire's tension as the control cycle read it this period, newtons.
    pub measured_tension_n: [f64; WIREMAN_WIRES],
    /// Every wire's torque command, N·m.
    pub torque_nm: [f64; WIREMAN_WIRES],
    /// Every pulley's speed, rad/s (positive: winding in).
    pub pulley_speed_rad_s: [f64; WIREMAN_WIRES],
}

/// What one experiment produced.
#[derive(Debug, Clone)]
pub struct Trace {
    /// One sample per control period.
    pub samples: Vec<TruthSample>,
    /// Safety state at the end of the run.
    pub final_safety: SafetyState,
    /// Periods run.
    pub cycles: u64,
    /// What the finger felt beyond what was asked, over the run (`docs/felt-force.md`).
    pub felt: FeltTally,
}

impl Trace {
    /// The samples whose time lies in `[from_s, to_s)`.
    pub fn window(&self, from_s: f64, to_s: f64) -> impl Iterator<Item = &TruthSample> {
        self.samples
            .iter()
            .filter(move |s| s.time_s >= from_s && s.time_s < to_s)
    }
}

/// An experiment: the configuration under test (algorithm, stiffness, damping, rate, sensor),
/// the surface, and the operator's script; the thimble starts where the demo scene puts it.
#[derive(Debug, Clone)]
pub struct Experiment<S = Plane> {
    /// The configuration the control cycle and the twin's parts are built from.
    pub config: Config,
    /// The surface rendered (a wall; a bas-relief when the felt surface is measured).
    pub surface: S,
    /// The operator (hand target path, hand stiffness and damping).
    pub operator: VirtualOperator,
    /// Simulated seconds to run.
    pub duration_s: f64,
    /// The parts between the control cycle and the plant.
    pub parts: Parts,
}

/// What stands between the control cycle and the plant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Parts {
    /// The configured parts' timing and resolution: CiA 402 drives (per-mille torque, the
    /// command applied at the next SYNC) and the configured converter.
    Faithful,
    /// Ideal parts: the torque applied as computed, the tension read at once.
    Ideal,
}

/// The twin inside a piece of simulated hardware.
trait HasTwin:
    Lifecycle + WireDrives<WIREMAN_WIRES> + TensionSensors<WIREMAN_WIRES> + EStop + AngleSensors + Clock
{
    fn model(&self) -> &videt_assembly::WiremanTwin;
}

impl HasTwin for videt_assembly::WiremanTwin {
    fn model(&self) -> &videt_assembly::WiremanTwin {
        self
    }
}

impl HasTwin for CanTwin<3, videt_assembly::WiremanTwin> {
    fn model(&self) -> &videt_assembly::WiremanTwin {
        self.twin()
    }
}

/// A surface an experiment renders: what the control loop takes as a fixed surface.
pub trait RenderedSurface:
    videt_control::Surface + videt_runtime::telemetry::surfaces::RecordSurface + Clone
{
}

impl<S> RenderedSurface for S where
    S: videt_control::Surface + videt_runtime::telemetry::surfaces::RecordSurface + Clone
{
}

/// Where the demo scene starts the thimble for `config` (in front of the frame's centre).
pub fn start_position(config: &Config) -> Vec3 {
    videt_assembly::twin_scene::wireman_wall_scene(config, 1)
        .twin
        .plant()
        .position_m()
}

/// Run `experiment`: the control loop on the stepped CAN twin, recording the twin's truth.
pub fn run<S: RenderedSurface>(experiment: &Experiment<S>) -> Result<Trace, String> {
    let config = &experiment.config;
    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(config, 7);
    scene.twin.set_operator(experiment.operator.clone());
    let rig = setup::rig(config).map_err(|e| e.to_string())?;
    let mut cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((experiment.duration_s * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let periods = (experiment.duration_s * f64::from(config.control.rate_hz)) as usize + 16;
    let report = match experiment.parts {
        Parts::Faithful => {
            // Simulated time runs faster than the nodes' real-time heartbeats: widen the
            // host's heartbeat tolerance accordingly.
            let mut drives = drive_config(config);
            drives.drive_heartbeat_timeout = std::time::Duration::from_secs(3600);
            let dictionary = videt_assembly::drive_dictionary::for_config(config)?;
            let hw = CanTwin::stepped(scene.twin, drives, dictionary)?;
            run_probed(hw, experiment, &mut cycle, &settings, periods, rig)?
        }
        Parts::Ideal => {
            scene.twin.set_sensor_converter(None);
            scene.twin.set_torque_step_nm(None);
            run_probed(scene.twin, experiment, &mut cycle, &settings, periods, rig)?
        }
    };
    let (report, samples, felt) = report;
    Ok(Trace {
        samples,
        final_safety: report.final_safety,
        cycles: report.cycles,
        felt,
    })
}

fn run_probed<H: HasTwin, S: RenderedSurface>(
    hw: H,
    experiment: &Experiment<S>,
    cycle: &mut videt_runtime::WiremanCycle,
    settings: &LoopSettings,
    periods: usize,
    rig: Rig3,
) -> Result<
    (
        videt_runtime::control_loop::LoopReport,
        Vec<TruthSample>,
        FeltTally,
    ),
    String,
> {
    let mut probe = Probe {
        hw,
        samples: Vec::with_capacity(periods),
        start: None,
        measured_n: [0.0; WIREMAN_WIRES],
    };
    start_hardware(&mut probe).map_err(|e| format!("the twin did not start: {e}"))?;
    let stop = AtomicBool::new(false);
    let mut felt = FeltObserver {
        step: setup::control_step_for(&experiment.config, rig),
        tally: FeltTally::new(),
    };
    let report = run_control_loop(
        &mut probe,
        &mut FixedSurface(experiment.surface.clone()),
        cycle,
        settings,
        &mut LoopControl::stop_flag(&stop),
        &mut felt,
        &mut LoopStats::default(),
    );
    Ok((report, probe.samples, felt.tally))
}

/// The felt-force measure of every period the loop runs.
struct FeltObserver {
    step: ControlStep<WIREMAN_WIRES, Rig3>,
    tally: FeltTally,
}

impl CycleObserver for FeltObserver {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if let Some(period) = crate::felt::felt_period(&self.step, record) {
            self.tally.add(&period);
        }
    }
}

/// Simulated hardware, the twin sampled after every torque command.
struct Probe<H> {
    hw: H,
    samples: Vec<TruthSample>,
    start: Option<MonoTime>,
    measured_n: [f64; WIREMAN_WIRES],
}

impl<H: HasTwin> Probe<H> {
    fn sample(&mut self, torque_nm: &[f64; WIREMAN_WIRES]) {
        let now = self.hw.now();
        let start = *self.start.get_or_insert(now);
        let plant = self.hw.model().plant();
        let position = plant.position_m();
        let tension = plant.tension_n();
        let mut force = Vec3::zeros();
        for (i, guide) in plant.params().device.guides_m().iter().enumerate() {
            let towards = guide - position;
            let norm = towards.norm();
            if norm > 1e-9 {
                force += towards / norm * tension[i];
            }
        }
        if self.samples.len() < self.samples.capacity() {
            self.samples.push(TruthSample {
                time_s: now.nanos_since(start) as f64 * 1e-9,
                position_m: position,
                velocity_m_s: plant.velocity_m_s(),
                wire_force_n: force,
                hand_force_n: plant.hand_force_n(),
                max_tension_n: tension.iter().copied().fold(0.0, f64::max),
                tension_n: tension,
                measured_tension_n: self.measured_n,
                torque_nm: *torque_nm,
                pulley_speed_rad_s: plant.pulley_speed_rad_s(),
            });
        }
    }
}

impl<H: HasTwin> ErrorType for Probe<H> {
    type Error = H::Error;
}

impl<H: HasTwin> Lifecycle for Probe<H> {
    fn configure(&mut self) -> Result<(), Self::Error> {
        self.hw.configure()
    }
    fn activate(&mut self) -> Result<(), Self::Error> {
        self.hw.activate()
    }
    fn deactivate(&mut self) -> Result<(), Self::Error> {
        self.hw.deactivate()
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.hw.lifecycle_state()
    }
}

impl<H: HasTwin> WireDrives<WIREMAN_WIRES> for Probe<H> {
    fn enable(&mut self) -> Result<(), Self::Error> {
        self.hw.enable()
    }
    fn disable(&mut self) -> Result<(), Self::Error> {
        self.hw.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        self.hw.read_drives(out)
    }
    fn write_torques(&mut self, torque_nm: &[f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        let r = self.hw.write_torques(torque_nm);
        self.sample(torque_nm);
        r
    }
}

impl<H: HasTwin> TensionSensors<WIREMAN_WIRES> for Probe<H> {
    fn read_tensions(&mut self, out_n: &mut [f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        let r = self.hw.read_tensions(out_n);
        self.measured_n = *out_n;
        r
    }
    fn read_fresh_tensions(
        &mut self,
        out_n: &mut [f64; WIREMAN_WIRES],
    ) -> Result<[bool; WIREMAN_WIRES], Self::Error> {
        let r = self.hw.read_fresh_tensions(out_n);
        self.measured_n = *out_n;
        r
    }
}

impl<H: HasTwin> AngleSensors for Probe<H> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), Self::Error> {
        self.hw.read_angles(out_rad)
    }
}

impl<H: HasTwin> EStop for Probe<H> {
    fn is_pressed(&mut self) -> Result<bool, Self::Error> {
        self.hw.is_pressed()
    }
    fn reset(&mut self) -> Result<(), Self::Error> {
        self.hw.reset()
    }
}

impl<H: HasTwin> Clock for Probe<H> {
    fn now(&self) -> MonoTime {
        self.hw.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.hw.sleep_until(deadline)
    }
}
