//! Auto-initialization and wire replacement run by the service itself, on its own hardware,
//! for a client of the control socket (`videt init` while `videtd` runs).
//!
//! The control thread owns the hardware. On a [`ControlCommand::HandOver`](videt_runtime::control_loop::ControlCommand::HandOver)
//! its loop ramps the forces out and returns with the drives still enabled and every wire at
//! minimum tension; the same thread — same priority, same core, same absolute-time period — then
//! runs the procedure ([`run_procedure`]: `session::measure` or `session::replace_wire_measure`
//! with a [`Runner`]), and afterwards goes back to the rendering loop: with a new control cycle
//! built from the new calibration when the client saved it, with the previous one otherwise.
//!
//! The socket's client thread and the control thread share a [`ProcedurePort`] /
//! [`ProcedureHandle`] pair made once at start-up ([`super::procedure_port`]): a preallocated
//! wait-free ring of [`ProcedureEvent`]s (control → client: stages, messages, prompts, the
//! measurement) and a few atomics (client → control: cancel, "the manual step is done", "the
//! calibration is saved"). The client thread computes the workspace and writes the file.
//!
//! The procedure mode is not the rendering cycle: it allocates at stage changes and at its end
//! (messages, the calibration record), as the tool's direct run does, never per period.

use std::cell::RefCell;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use videt_assembly::WiremanTwin as Twin;
use videt_runtime::WIREMAN_WIRES;

use videt_config::Config;
use videt_control::autoinit::{Failure, Stage};
use videt_control::safety::SafetyState;
use videt_control::Rig3;
use videt_hal::{Clock, DriveSample, EStop, ErrorType, MonoTime, TensionSensors, WireDrives};
use videt_sim::{VirtualOperator, WireModules};

use super::commission::{check_rig, CommissionStep, CommissionTechnician, Thimble};
use super::corrected::CorrectedTensions;
use super::runner::{InitHardware, Readings, Runner};
use super::session::{
    self, run_settings, FlowContext, InitError, Measurement, Request, Technician,
};
use super::twin::{hold_after_action, SimTechnician, TwinSetup};
use videt_assembly::can_twin::{CanTwin, TwinDevice};
use videt_assembly::twin_rt::RealTimeTwin;
use videt_runtime::control_loop::{CycleObserver, WindowStats};
use videt_runtime::cycle::{CycleRecord, WireZero};

pub use super::procedure_port::{
    procedure_channel, saved, ProcedureControl, ProcedureEvent, ProcedureHandle, ProcedureKind,
    ProcedurePort, ProcedureSession, ProcedureSpec, Text, EVENT_RING, MESSAGE_BYTES,
};

/// Progress events per second while the procedure runs.
pub const PROGRESS_HZ: u32 = 2;
/// How long the control thread waits for the client to compute the workspace and save the
/// calibration, seconds.
pub const SAVE_WAIT_S: f64 = 30.0;

/// The service's hardware as a procedure sees it: the HAL, and on the digital twin the model,
/// so the twin's simulated technician can do the manual steps.
pub trait ProcedureDevice: InitHardware {
    /// The twin, when the hardware is one.
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        None
    }

    /// Read the tensions as the sensors give them (`true`: the tension calibration's
    /// correction left out, as the commissioning check needs) or corrected (`false`, the
    /// default). Hardware without a correction reads them raw either way.
    fn use_raw_tensions(&mut self, _raw: bool) {}

    /// The handles that inject faults into the running twin (its physics, and its simulated
    /// bus and drives when it has them); `None` on the device.
    fn sim_faults(&mut self) -> Option<videt_assembly::sim_faults::SimFaultPort> {
        self.twin_mut()
            .map(|t| videt_assembly::sim_faults::SimFaultPort {
                twin: t.fault_inbox(),
                bus: None,
                drives: Vec::new(),
                vision_stall: None,
                wires: WIREMAN_WIRES,
            })
    }
}

impl ProcedureDevice for Twin {
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        Some(self)
    }
}

impl ProcedureDevice for RealTimeTwin<3, videt_control::Rig3> {
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        Some(RealTimeTwin::twin_mut(self))
    }
}

impl<H: ProcedureDevice> ProcedureDevice for CorrectedTensions<H> {
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        self.inner_mut().twin_mut()
    }
    fn sim_faults(&mut self) -> Option<videt_assembly::sim_faults::SimFaultPort> {
        self.inner_mut().sim_faults()
    }
    fn use_raw_tensions(&mut self, raw: bool) {
        self.set_correcting(!raw);
        self.inner_mut().use_raw_tensions(raw);
    }
}

impl<T: TwinDevice<3, Device = videt_control::Rig3>> ProcedureDevice for CanTwin<3, T> {
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        Some(CanTwin::twin_mut(self))
    }
    fn sim_faults(&mut self) -> Option<videt_assembly::sim_faults::SimFaultPort> {
        Some(CanTwin::sim_faults(self))
    }
}

/// What the twin looked like before the procedure took it (restored afterwards).
struct TwinScene {
    modules: WireModules<WIREMAN_WIRES>,
    operator: VirtualOperator,
    position_m: videt_sim::Vec3,
}

/// Put the twin at rest for a procedure: the operator's finger out of the thimble, every wire
/// detached and fully wound (the encoders keep counting: their zeros do not move).
fn twin_to_rest(twin: &mut Twin) -> TwinScene {
    let scene = TwinScene {
        modules: twin.plant().modules().clone(),
        operator: twin.operator().clone(),
        position_m: twin.plant().position_m(),
    };
    twin.set_operator(VirtualOperator::absent(0.2));
    let plant = twin.plant_mut();
    plant.set_modules(WireModules::paper());
    plant.rest_detached();
    scene
}

/// The wearer puts the finger back in: the thimble where it was, wires taut, the operator's
/// script restarted now.
fn twin_from_rest(twin: &mut Twin, scene: TwinScene) {
    let plant = twin.plant_mut();
    plant.connect_wires_at(scene.position_m);
    plant.set_modules(scene.modules);
    let now_s = twin.plant().time_s();
    twin.set_operator(scene.operator.starting_at(now_s));
}

/// The hardware during a procedure: every period is published as a record (status, telemetry,
/// watchdog keep going) and a few times a second as a progress event.
struct Observed<'a, H, O: ?Sized> {
    hw: &'a mut H,
    observer: &'a mut O,
    events: &'a RefCell<rtrb::Producer<ProcedureEvent>>,
    record: CycleRecord,
    window: WindowStats,
    window_start: MonoTime,
    window_cycles: u64,
    started: MonoTime,
    start_counts: Option<[i64; WIREMAN_WIRES]>,
    counts: [i64; WIREMAN_WIRES],
    wire_zero: WireZero,
    metres_per_count: f64,
    progress_every: u64,
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> Observed<'_, H, O> {
    fn travel_m(&self) -> [f64; WIREMAN_WIRES] {
        let start = self.start_counts.unwrap_or([0; WIREMAN_WIRES]);
        core::array::from_fn(|i| (start[i] - self.counts[i]) as f64 * self.metres_per_count)
    }
}

impl<H: ErrorType, O: ?Sized> ErrorType for Observed<'_, H, O> {
    type Error = H::Error;
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> WireDrives<WIREMAN_WIRES>
    for Observed<'_, H, O>
{
    fn enable(&mut self) -> Result<(), Self::Error> {
        self.hw.enable()
    }
    fn disable(&mut self) -> Result<(), Self::Error> {
        self.hw.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        let r = self.hw.read_drives(out);
        let counts: [i64; WIREMAN_WIRES] = core::array::from_fn(|i| out[i].position_counts);
        if self.start_counts.is_none() {
            self.start_counts = Some(counts);
        }
        self.counts = counts;
        for (i, c) in counts.iter().enumerate() {
            self.record.lengths_m[i] =
                self.wire_zero.length_at_zero_m[i] - *c as f64 * self.metres_per_count;
        }
        r
    }
    fn write_torques(&mut self, torque_nm: &[f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        let r = self.hw.write_torques(torque_nm);
        let now = self.hw.now();
        self.record.time = now;
        self.record.torque_nm = *torque_nm;
        self.window_cycles += 1;
        let window_ns = now.nanos_since(self.window_start);
        if window_ns >= 1_000_000_000 {
            self.window.rate_hz = self.window_cycles as f64 * 1e9 / window_ns as f64;
            self.window_start = now;
            self.window_cycles = 0;
        }
        self.observer.observe(&self.record, &self.window);
        if self.record.cycle.is_multiple_of(self.progress_every) {
            let event = ProcedureEvent::Progress {
                elapsed_s: now.nanos_since(self.started) as f64 * 1e-9,
                travel_m: self.travel_m(),
                tension_n: self.record.tension_measured_n,
            };
            push_if_room(self.events, event);
        }
        self.record.cycle += 1;
        r
    }
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> TensionSensors<WIREMAN_WIRES>
    for Observed<'_, H, O>
{
    fn read_tensions(&mut self, out_n: &mut [f64; WIREMAN_WIRES]) -> Result<(), Self::Error> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }
    fn read_fresh_tensions(
        &mut self,
        out_n: &mut [f64; WIREMAN_WIRES],
    ) -> Result<[bool; WIREMAN_WIRES], Self::Error> {
        let r = self.hw.read_fresh_tensions(out_n);
        self.record.tension_measured_n = *out_n;
        r
    }
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> EStop for Observed<'_, H, O> {
    fn is_pressed(&mut self) -> Result<bool, Self::Error> {
        self.hw.is_pressed()
    }
    fn reset(&mut self) -> Result<(), Self::Error> {
        self.hw.reset()
    }
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> Clock for Observed<'_, H, O> {
    fn now(&self) -> MonoTime {
        self.hw.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.hw.sleep_until(deadline)
    }
}

impl<H: ProcedureDevice, O: CycleObserver + ?Sized> ProcedureDevice for Observed<'_, H, O> {
    fn twin_mut(&mut self) -> Option<&mut Twin> {
        self.hw.twin_mut()
    }
    fn use_raw_tensions(&mut self, raw: bool) {
        self.hw.use_raw_tensions(raw);
    }
}

/// Events that may be dropped leave this much room for the ones that may not.
const RESERVED_SLOTS: usize = 16;

fn push_if_room(events: &RefCell<rtrb::Producer<ProcedureEvent>>, event: ProcedureEvent) {
    let mut events = events.borrow_mut();
    if events.slots() > RESERVED_SLOTS {
        let _ = events.push(event);
    }
}

fn push(events: &RefCell<rtrb::Producer<ProcedureEvent>>, event: ProcedureEvent) -> bool {
    events.borrow_mut().push(event).is_ok()
}

/// The technician for a procedure run by the service: each manual step becomes a prompt to the
/// client, who confirms it (or, on the twin, the simulated technician does it at once).
struct ServiceTechnician<'a> {
    events: &'a RefCell<rtrb::Producer<ProcedureEvent>>,
    control: &'a ProcedureControl,
    yes: bool,
    simulated: Option<SimTechnician>,
    /// The commissioning step under way: whether the client must confirm it, and the
    /// confirmations counted when it was asked for.
    check_step: (bool, u32),
}

impl<H: ProcedureDevice> Technician<H> for ServiceTechnician<'_> {
    fn perform(
        &mut self,
        request: Request,
        hw: &mut H,
        runner: &mut Runner,
        stop: &std::sync::atomic::AtomicBool,
    ) -> Result<(), Failure> {
        let seen = self.control.confirmations.load(Ordering::Acquire);
        let simulated = self.simulated.is_some() && hw.twin_mut().is_some();
        let confirm = !simulated && !self.yes;
        if !push(self.events, ProcedureEvent::Prompt { request, confirm }) && confirm {
            // The client would never see the question.
            return Err(Failure::Cancelled);
        }
        if let (Some(tech), Some(twin)) = (self.simulated.as_mut(), hw.twin_mut()) {
            tech.act(request, twin)?;
            return hold_after_action(hw, runner, request.released_wire(), stop);
        }
        if !confirm {
            return Ok(());
        }
        let confirmations = &self.control.confirmations;
        runner.hold_until(
            hw,
            request.released_wire(),
            stop,
            &mut || confirmations.load(Ordering::Acquire) != seen,
            &mut |_| {},
        )
    }

    fn inform(&mut self, message: &str) {
        push_if_room(self.events, ProcedureEvent::Message(Text::new(message)));
    }

    fn stage(&mut self, stage: Stage, readings: &Readings) {
        push_if_room(
            self.events,
            ProcedureEvent::Stage {
                stage,
                counts: readings.input.counts,
                tension_n: readings.tension_n,
            },
        );
    }
}

impl<H: ProcedureDevice> CommissionTechnician<H> for ServiceTechnician<'_> {
    fn perform_commission(&mut self, step: CommissionStep, hw: &mut H) -> Result<(), Failure> {
        let seen = self.control.confirmations.load(Ordering::Acquire);
        let simulated = self.simulated.is_some() && hw.twin_mut().is_some();
        let confirm = !simulated && !self.yes;
        self.check_step = (confirm, seen);
        if !push(self.events, ProcedureEvent::CheckPrompt { step, confirm }) && confirm {
            // The client would never see the question.
            return Err(Failure::Cancelled);
        }
        if let (Some(tech), Some(twin)) = (self.simulated.as_mut(), hw.twin_mut()) {
            tech.perform_commission(step, twin)?;
        }
        Ok(())
    }

    fn commission_step_done(&mut self, _step: CommissionStep, _hw: &mut H) -> bool {
        let (confirm, seen) = self.check_step;
        !confirm || self.control.confirmations.load(Ordering::Acquire) != seen
    }
}

/// How a procedure run by the service ended, for the control thread.
#[derive(Debug, Clone, Copy)]
pub struct ProcedureEnd {
    /// The new calibration, when the client saved one (`None`: keep the previous one).
    pub recalibration: Option<Recalibration>,
    /// A safe state the rendering must start in and keep (a commissioning check that found
    /// the rig not as configured).
    pub trip: Option<SafetyState>,
    /// The next period's number.
    pub next_cycle: u64,
}

/// The service's calibration after a procedure.
#[derive(Debug, Clone, Copy)]
pub struct Recalibration {
    /// The measured rig.
    pub rig: Rig3,
    /// The new encoder zeros.
    pub wire_zero: WireZero,
}

/// Run the procedure the client submitted on the control thread, on hardware the rendering
/// loop handed over (drives enabled, wires at minimum tension). `observer` receives a record
/// every period, numbered from `first_cycle`; `wire_zero` and `safety` are the service's current
/// ones (for the records). Returns the new calibration when the client saved it, the safe state
/// to keep, and the next period number.
pub fn run_procedure<H, O>(
    hw: &mut H,
    handle: &mut ProcedureHandle,
    config: &Config,
    observer: &mut O,
    first_cycle: u64,
    wire_zero: WireZero,
    safety: SafetyState,
) -> ProcedureEnd
where
    H: ProcedureDevice,
    O: CycleObserver + ?Sized,
{
    // Never wait on the control thread: the slot is only contended while the client withdraws
    // its request, which then has nothing to hand over either.
    let Some(spec) = handle.spec.try_lock().ok().and_then(|mut s| s.take()) else {
        // A hand-over nobody waits for any more (the client gave up): render again.
        return ProcedureEnd {
            recalibration: None,
            trip: None,
            next_cycle: first_cycle,
        };
    };
    let control = Arc::clone(&handle.control);
    control.running.store(true, Ordering::Release);
    let events = &handle.events;
    let twin = hw.twin_mut().is_some();
    let _ = push(
        events,
        ProcedureEvent::Started {
            kind: spec.kind,
            twin,
        },
    );
    let scene = hw.twin_mut().map(twin_to_rest);

    let mut config = config.clone();
    if let Some(l) = spec.sim_new_wire_length_m {
        // Winding a long new yarn back must not count as a runaway.
        config.autoinit.max_wind_travel_m = config.autoinit.max_wind_travel_m.max(l + 0.1);
    }
    let mut runner = Runner::new(run_settings(&config));
    let simulated = twin.then(|| {
        let mut setup = TwinSetup::from_config(&config, spec.sim_seed);
        setup.faults = spec.sim_faults.clone();
        let mut tech = SimTechnician::new(&setup);
        if let Some(l) = spec.sim_new_wire_length_m {
            tech.set_new_wire_length_m(l);
        }
        tech
    });
    let mut tech = ServiceTechnician {
        events,
        control: &control,
        yes: spec.yes,
        simulated,
        check_step: (false, 0),
    };
    let now = hw.now();
    let rate_hz = config.control.rate_hz.max(1);
    let mut observed = Observed {
        hw,
        observer,
        events,
        record: CycleRecord {
            cycle: first_cycle,
            safety,
            released_wire: -1,
            ..CycleRecord::default()
        },
        window: WindowStats::default(),
        window_start: now,
        window_cycles: 0,
        started: now,
        start_counts: None,
        counts: [0; WIREMAN_WIRES],
        wire_zero,
        metres_per_count: runner.settings().transmission.metres_per_count(),
        progress_every: u64::from((rate_hz / PROGRESS_HZ).max(1)),
    };
    let ctx = FlowContext {
        config: &config,
        source: if twin { "twin" } else { "device" },
        stop: &control.cancel,
    };
    let measured = match spec.kind {
        ProcedureKind::Commission => None,
        ProcedureKind::Initialize => Some(session::measure(
            &mut observed,
            &mut tech,
            &mut runner,
            &ctx,
        )),
        ProcedureKind::ReplaceWire {
            wire,
            required_length_m,
        } => Some(session::replace_wire_measure(
            &mut observed,
            &mut tech,
            &mut runner,
            &ctx,
            wire,
            required_length_m,
        )),
    };
    let (recalibration, trip) = match measured {
        Some(result) => (
            deliver_measurement(&mut observed, &mut runner, events, &control, result),
            None,
        ),
        None => (
            None,
            commission(
                &mut observed,
                &mut tech,
                &mut runner,
                &config,
                &control,
                safety,
            ),
        ),
    };
    let next_cycle = observed.record.cycle;
    if let (Some(scene), Some(twin)) = (scene, observed.hw.twin_mut()) {
        twin_from_rest(twin, scene);
    }
    control.running.store(false, Ordering::Release);
    ProcedureEnd {
        recalibration,
        trip,
        next_cycle,
    }
}

/// A measurement's end: the result to the client and, when it measured the rig and the client
/// saved the calibration, the service's new one.
fn deliver_measurement<H: ProcedureDevice>(
    hw: &mut H,
    runner: &mut Runner,
    events: &RefCell<rtrb::Producer<ProcedureEvent>>,
    control: &ProcedureControl,
    result: Result<Measurement, InitError>,
) -> Option<Recalibration> {
    // The control cycle's rig, as a loaded calibration file would give it.
    let result = result.and_then(|m| {
        videt_runtime::calibration::rig_from_sides(&m.triangle.sides_m)
            .map(|rig| (m, rig))
            .map_err(InitError::Unusable)
    });
    let pay_out = [runner.settings().pay_out_tension_n; WIREMAN_WIRES];
    match result {
        Ok((measurement, rig)) => {
            let wire_zero = WireZero {
                length_at_zero_m: measurement.length_at_zero_m(),
            };
            let finished = ProcedureEvent::Finished(Box::new(Ok(measurement)));
            (deliver(hw, runner, events, finished, pay_out)
                && wait_until_saved(hw, runner, control))
            .then_some(Recalibration { rig, wire_zero })
        }
        Err(e) => {
            let finished = ProcedureEvent::Finished(Box::new(Err(e)));
            let _ = deliver(hw, runner, events, finished, pay_out);
            None
        }
    }
}

/// The commissioning check on the service's rig, its thimble on the wires: the tensions read
/// raw meanwhile, its report delivered to the client. `safety` is the service's state when it
/// handed the rig over. Returns the safe state to keep when the rig is not as configured.
fn commission<H: ProcedureDevice>(
    hw: &mut H,
    tech: &mut ServiceTechnician<'_>,
    runner: &mut Runner,
    config: &Config,
    control: &ProcedureControl,
    safety: SafetyState,
) -> Option<SafetyState> {
    hw.use_raw_tensions(true);
    let mut found = check_rig(hw, tech, runner, config, &control.cancel, Thimble::On);
    hw.use_raw_tensions(false);
    if matches!(found.stopped, Some(Failure::DriveFault { .. })) && safety.power_off() {
        // Drives a fault powered off stay off until the service restarts.
        found.detail = Some(format!(
            "the service's drives are off since its {} stop: stop videtd (systemctl stop videtd) and run videt commission directly",
            safety.as_str()
        ));
    }
    let trip = found.safe_state();
    // Wires that wind as configured keep the thimble taut; any other gets no torque.
    let hold = if found.as_configured() && found.stopped.is_none() {
        [runner.settings().pay_out_tension_n; WIREMAN_WIRES]
    } else {
        [0.0; WIREMAN_WIRES]
    };
    let checked = ProcedureEvent::Checked(Box::new(found));
    let _ = deliver(hw, runner, tech.events, checked, hold);
    trip
}

/// Push the final event, the wires pulled with `hold` (N) while the ring is full (bounded:
/// 5 s). Faults do not stop it: the client must hear how the procedure ended.
fn deliver<H: ProcedureDevice>(
    hw: &mut H,
    runner: &mut Runner,
    events: &RefCell<rtrb::Producer<ProcedureEvent>>,
    event: ProcedureEvent,
    hold: [f64; WIREMAN_WIRES],
) -> bool {
    let mut pending = event;
    let limit = 5 * u64::from(runner.settings().rate_hz.max(1));
    for _ in 0..limit {
        match events.borrow_mut().push(pending) {
            Ok(()) => return true,
            Err(rtrb::PushError::Full(e)) => pending = e,
        }
        runner.period(hw, &hold, None);
    }
    false
}

/// Hold the wires until the client says whether it saved the calibration (bounded); true when
/// it did.
fn wait_until_saved<H: ProcedureDevice>(
    hw: &mut H,
    runner: &mut Runner,
    control: &ProcedureControl,
) -> bool {
    let limit = (SAVE_WAIT_S * f64::from(runner.settings().rate_hz.max(1))) as u64;
    let hold = [runner.settings().pay_out_tension_n; WIREMAN_WIRES];
    let mut disabled = false;
    for period in 0.. {
        let state = control.saved.load(Ordering::Acquire);
        if state == saved::SAVED || state == saved::NOT_SAVED {
            break;
        }
        // Too late: unless it is being written, the client must not save it now.
        if period >= limit
            && control
                .saved
                .compare_exchange(
                    saved::PENDING,
                    saved::NOT_SAVED,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                )
                .is_ok()
        {
            break;
        }
        if period >= 2 * limit {
            // A write that never ends: the file may be written, the service keeps the
            // calibration it renders with (a restart loads the file).
            break;
        }
        // A faulted or stopped device is not commanded further here; the control cycle's
        // supervisor takes over as soon as this returns.
        let (r, _) = runner.period(hw, &hold, None);
        if !disabled && (r.input.estop_pressed || r.input.drive_fault.is_some()) {
            // Once: the drives stay disabled, no bus command is repeated every period.
            let _ = hw.disable();
            disabled = true;
        }
    }
    control.saved.load(Ordering::Acquire) == saved::SAVED
}
