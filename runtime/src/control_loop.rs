//! The periodic control loop: absolute-time wake-ups, latency and compute-time histograms,
//! overrun policy, commands from the supervisor, start-up and clean shutdown. Runs the same on
//! the device and on the twin (whose simulated clock makes the loop faster than real time and
//! deterministic).
//!
//! Everything here runs on the control thread: no allocation, no locks, no formatting; the
//! only blocking call is the clock's absolute sleep (and the HAL's bus I/O).

use std::sync::atomic::{AtomicBool, Ordering};

use videt_control::safety::{SafetyReason, SafetyState};
use videt_control::WireDevice;
use videt_hal::{AngleSensors, Clock, EStop, Lifecycle, TensionSensors, WireDrives};

use crate::cycle::{ControlCycle, CycleRecord};
use crate::histogram::Histogram;
use crate::snapshot::SurfaceFeed;

/// Set by the panic hook when any thread of the service panics: the loop then goes to the safe
/// state and stops.
pub static SERVICE_PANICKED: AtomicBool = AtomicBool::new(false);

/// Settings of the loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSettings {
    /// Rate, Hz.
    pub rate_hz: u32,
    /// Run this long, then shut down cleanly (`None`: until stopped).
    pub duration_ns: Option<u64>,
    /// This many overruns in a row force the minimum-tension safe state.
    pub max_consecutive_overruns: u32,
}

impl LoopSettings {
    /// The period, nanoseconds.
    pub fn period_ns(&self) -> u64 {
        1_000_000_000 / u64::from(self.rate_hz.max(1))
    }
}

/// A command from the supervisor to the control thread (through a wait-free queue).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlCommand {
    /// Ramp the forces out and stop.
    Stop,
    /// Release a wire for replacement (no forces; that wire unpowered).
    ReleaseWire(u8),
    /// Leave the released-wire mode.
    Resume,
    /// Clear latched faults that do not need a restart.
    ResetFaults,
    /// Ramp the forces out and hand the (still enabled) hardware to a procedure run on the
    /// control thread (auto-initialization through the control socket): the loop returns with
    /// [`LoopReport::handed_over`] set.
    HandOver,
}

/// Timing of the last complete one-second window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WindowStats {
    /// Achieved rate over the window, Hz.
    pub rate_hz: f64,
    /// Worst compute time in the window, nanoseconds.
    pub worst_compute_ns: u64,
    /// Worst wake-up latency in the window, nanoseconds.
    pub worst_latency_ns: u64,
    /// Overruns since start.
    pub overruns_total: u64,
}

/// Whole-run statistics, preallocated by the caller.
#[derive(Debug, Clone, Default)]
pub struct LoopStats {
    /// Wake-up latency per period, nanoseconds.
    pub latency: Histogram,
    /// Compute time per period (wake-up to end of work), nanoseconds.
    pub compute: Histogram,
    /// Periods whose work ended after the next deadline.
    pub overruns: u64,
    /// Periods run.
    pub cycles: u64,
}

/// Receives every period's record. Called on the control thread: must not block or allocate.
pub trait CycleObserver {
    /// One period finished.
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats);
}

impl CycleObserver for () {
    fn observe(&mut self, _record: &CycleRecord, _window: &WindowStats) {}
}

impl<A: CycleObserver, B: CycleObserver> CycleObserver for (A, B) {
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats) {
        self.0.observe(record, window);
        self.1.observe(record, window);
    }
}

impl<A: CycleObserver, B: CycleObserver, C: CycleObserver> CycleObserver for (A, B, C) {
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats) {
        self.0.observe(record, window);
        self.1.observe(record, window);
        self.2.observe(record, window);
    }
}

/// How the loop ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopReport {
    /// Periods run.
    pub cycles: u64,
    /// Periods whose work ended after the next deadline.
    pub overruns: u64,
    /// Safety state at the end.
    pub final_safety: SafetyState,
    /// The loop ended to hand the hardware over ([`ControlCommand::HandOver`]): the drives are
    /// still enabled, every wire at minimum tension.
    pub handed_over: bool,
    /// What made the loop stop.
    pub ended_by: LoopEnd,
}

/// What made the loop stop (the stop's ramp then ran to its end).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LoopEnd {
    /// [`LoopControl::stop`] was raised (by a signal's handler, in the service).
    StopFlag,
    /// A [`ControlCommand::Stop`] (the control socket's `stop`).
    StopCommand,
    /// [`LoopSettings::duration_ns`] elapsed.
    DurationElapsed,
    /// A panic elsewhere in the service ([`SERVICE_PANICKED`]).
    Panic,
    /// A [`ControlCommand::HandOver`].
    HandOver,
}

/// The loop could not start.
#[derive(Debug, thiserror::Error)]
#[error("cannot start the control loop: {stage} failed ({kind}): {detail}")]
pub struct StartError {
    /// What failed: `configure`, `activate` or `enable`.
    pub stage: &'static str,
    /// The device error kind.
    pub kind: videt_hal::ErrorKind,
    /// The device's own account of the failure (which drive, which object, how long it waited).
    pub detail: String,
}

impl StartError {
    fn new(stage: &'static str, e: &impl videt_hal::Error) -> StartError {
        StartError {
            stage,
            kind: e.kind(),
            detail: e.to_string(),
        }
    }
}

/// Bring the hardware up: configure, activate, enable the drives.
pub fn start_hardware<const N: usize, H: Lifecycle + WireDrives<N>>(
    hw: &mut H,
) -> Result<(), StartError> {
    hw.configure()
        .map_err(|e| StartError::new("configure", &e))?;
    hw.activate().map_err(|e| StartError::new("activate", &e))?;
    hw.enable().map_err(|e| StartError::new("enable", &e))?;
    Ok(())
}

/// What steers the loop from outside.
pub struct LoopControl<'a> {
    /// Set (by a signal handler) to ramp out and stop.
    pub stop: &'a AtomicBool,
    /// Commands from the supervisor.
    pub commands: Option<&'a mut rtrb::Consumer<ControlCommand>>,
}

impl<'a> LoopControl<'a> {
    /// Steered by a stop flag only.
    pub fn stop_flag(stop: &'a AtomicBool) -> LoopControl<'a> {
        LoopControl {
            stop,
            commands: None,
        }
    }
}

/// Run the loop until stopped (signal, command, duration, or a panic elsewhere in the service),
/// then ramp the forces out, power the drives off and return. The hardware must have been
/// started with [`start_hardware`]; `stats` is filled in place.
pub fn run_control_loop<const N: usize, D, H, F, O>(
    hw: &mut H,
    surfaces: &mut F,
    cycle: &mut ControlCycle<N, D>,
    settings: &LoopSettings,
    control: &mut LoopControl<'_>,
    observer: &mut O,
    stats: &mut LoopStats,
) -> LoopReport
where
    D: WireDevice<N>,
    H: Lifecycle + WireDrives<N> + TensionSensors<N> + EStop + AngleSensors + Clock,
    F: SurfaceFeed + ?Sized,
    O: CycleObserver + ?Sized,
{
    let period = settings.period_ns();
    let start = hw.now();
    let end = settings.duration_ns.map(|d| start.add_nanos(d));
    let mut next = start.add_nanos(period);
    let mut record = CycleRecord::default();
    let mut window = WindowStats::default();
    let (mut window_start, mut window_cycles) = (start, 0u64);
    let (mut worst_compute, mut worst_latency) = (0u64, 0u64);
    let mut consecutive_overruns = 0u32;
    let mut stopping = false;
    let mut handing_over = false;
    let mut stop_commanded = false;
    // Set when the stop begins: the loop ends only after that.
    let mut ended_by = LoopEnd::StopFlag;

    loop {
        hw.sleep_until(next);
        let woke = hw.now();
        let latency = woke.nanos_since(next);

        if let Some(commands) = control.commands.as_deref_mut() {
            while let Ok(command) = commands.pop() {
                match command {
                    ControlCommand::Stop => {
                        stop_commanded = true;
                        control.stop.store(true, Ordering::Relaxed);
                    }
                    ControlCommand::ReleaseWire(w) => cycle.release_wire(Some(usize::from(w))),
                    ControlCommand::Resume => cycle.release_wire(None),
                    ControlCommand::ResetFaults => cycle.reset_faults(),
                    ControlCommand::HandOver if !stopping => {
                        stopping = true;
                        handing_over = true;
                        ended_by = LoopEnd::HandOver;
                        cycle.release_wire(None);
                        cycle.request_stop();
                    }
                    ControlCommand::HandOver => {}
                }
            }
        }
        let panicked = SERVICE_PANICKED.load(Ordering::Relaxed);
        if panicked {
            cycle.trip(SafetyState::MinimumTension(SafetyReason::SoftwareFault));
        }
        let stop_raised = control.stop.load(Ordering::Relaxed);
        if (!stopping || handing_over)
            && (panicked || stop_raised || end.is_some_and(|e| woke >= e))
        {
            ended_by = if panicked {
                LoopEnd::Panic
            } else if stop_commanded {
                LoopEnd::StopCommand
            } else if stop_raised {
                LoopEnd::StopFlag
            } else {
                LoopEnd::DurationElapsed
            };
            // A real stop wins over a hand-over.
            stopping = true;
            handing_over = false;
            cycle.request_stop();
        }
        let overrun_trip = consecutive_overruns >= settings.max_consecutive_overruns;
        record.wake_latency_ns = latency;
        cycle.run(hw, surfaces.current(), woke, overrun_trip, &mut record);
        let done = hw.now();
        record.compute_ns = done.nanos_since(woke);
        stats.cycles += 1;
        stats.latency.record(latency);
        stats.compute.record(record.compute_ns);

        window_cycles += 1;
        worst_compute = worst_compute.max(record.compute_ns);
        worst_latency = worst_latency.max(latency);
        let window_ns = woke.nanos_since(window_start);
        if window_ns >= 1_000_000_000 {
            window = WindowStats {
                rate_hz: window_cycles as f64 * 1e9 / window_ns as f64,
                worst_compute_ns: worst_compute,
                worst_latency_ns: worst_latency,
                overruns_total: stats.overruns,
            };
            window_start = woke;
            window_cycles = 0;
            worst_compute = 0;
            worst_latency = 0;
        }
        observer.observe(&record, &window);

        if stopping && cycle.stop_finished() {
            break;
        }
        next = next.add_nanos(period);
        if done > next {
            stats.overruns += 1;
            consecutive_overruns = consecutive_overruns.saturating_add(1);
            // Keep the grid: skip the periods that are already gone.
            let behind = done.nanos_since(next) / period + 1;
            next = next.add_nanos(behind * period);
        } else {
            consecutive_overruns = 0;
        }
        if overrun_trip {
            cycle.trip(SafetyState::MinimumTension(SafetyReason::DeadlineOverrun));
        }
    }
    if !handing_over {
        let _ = hw.disable();
        let _ = hw.deactivate();
    }
    LoopReport {
        cycles: stats.cycles,
        overruns: stats.overruns,
        final_safety: cycle.safety_state(),
        handed_over: handing_over,
        ended_by,
    }
}
