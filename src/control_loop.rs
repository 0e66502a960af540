//! The periodic control loop: absolute-time wake-ups, latency and compute-time accounting,
//! overrun policy, start-up and clean shutdown. Runs the same on the device and on the twin (whose
//! simulated clock makes the loop faster than real time and deterministic).

use std::sync::atomic::{AtomicBool, Ordering};

use videt_control::safety::{SafetyReason, SafetyState};
use videt_control::Surface;
use videt_hal::{Clock, EStop, Error, Lifecycle, TensionSensors, WireDrives};

use crate::cycle::{ControlCycle, CycleRecord};

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

/// Receives every period's record. Called on the control thread: must not block or allocate.
pub trait CycleObserver {
    /// One period finished.
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats);
}

/// An observer that ignores everything.
impl CycleObserver for () {
    fn observe(&mut self, _record: &CycleRecord, _window: &WindowStats) {}
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
}

/// The loop could not start.
#[derive(Debug, thiserror::Error)]
#[error("cannot start the control loop: {stage} failed ({kind})")]
pub struct StartError {
    /// What failed: `configure`, `activate` or `enable`.
    pub stage: &'static str,
    /// The device error kind.
    pub kind: videt_hal::ErrorKind,
}

/// Bring the hardware up: configure, activate, enable the drives.
pub fn start_hardware<H: Lifecycle + WireDrives>(hw: &mut H) -> Result<(), StartError> {
    hw.configure().map_err(|e| StartError {
        stage: "configure",
        kind: e.kind(),
    })?;
    hw.activate().map_err(|e| StartError {
        stage: "activate",
        kind: e.kind(),
    })?;
    hw.enable().map_err(|e| StartError {
        stage: "enable",
        kind: e.kind(),
    })?;
    Ok(())
}

/// Run the loop until `stop` is set (or the duration passes), then ramp the forces out, power
/// the drives off and return. The hardware must have been started with [`start_hardware`].
pub fn run_control_loop<H, S, O>(
    hw: &mut H,
    surface: &S,
    cycle: &mut ControlCycle,
    settings: &LoopSettings,
    stop: &AtomicBool,
    observer: &mut O,
) -> LoopReport
where
    H: Lifecycle + WireDrives + TensionSensors + EStop + Clock,
    S: Surface + ?Sized,
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
    let (mut overruns, mut consecutive_overruns, mut cycles) = (0u64, 0u32, 0u64);
    let mut stopping = false;

    loop {
        hw.sleep_until(next);
        let woke = hw.now();
        let latency = woke.nanos_since(next);
        if !stopping && (stop.load(Ordering::Relaxed) || end.is_some_and(|e| woke >= e)) {
            stopping = true;
            cycle.request_stop();
        }
        let overrun_trip = consecutive_overruns >= settings.max_consecutive_overruns;
        record.wake_latency_ns = latency;
        cycle.run(hw, surface, woke, overrun_trip, &mut record);
        let done = hw.now();
        record.compute_ns = done.nanos_since(woke);
        cycles += 1;

        window_cycles += 1;
        worst_compute = worst_compute.max(record.compute_ns);
        worst_latency = worst_latency.max(latency);
        let window_ns = woke.nanos_since(window_start);
        if window_ns >= 1_000_000_000 {
            window = WindowStats {
                rate_hz: window_cycles as f64 * 1e9 / window_ns as f64,
                worst_compute_ns: worst_compute,
                worst_latency_ns: worst_latency,
                overruns_total: overruns,
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
            overruns += 1;
            consecutive_overruns += 1;
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
    let _ = hw.disable();
    let _ = hw.deactivate();
    LoopReport {
        cycles,
        overruns,
        final_safety: cycle.safety_state(),
    }
}
