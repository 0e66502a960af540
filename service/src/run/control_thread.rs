//! The control thread: SCHED_FIFO on its CPU, the hardware started, the control loop run with
//! the observers (status, session log, thimble readers, live view), and the procedures the
//! control socket hands over run in the same thread, at the same priority and period; the
//! drives powered off if anything in it panics.

use std::panic::AssertUnwindSafe;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use tracing::warn;
use videt_config::Config;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopReport, LoopSettings,
    LoopStats,
};
use videt_runtime::cycle::ControlCycle;
use videt_runtime::rt;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::snapshot::SurfaceFeed;
use videt_runtime::status::StatusPublisher;
use videt_runtime::telemetry::{CalibrationInForce, TelemetryProducer};
use videt_runtime::thimble::ThimblePublisher;

use crate::init::remote::ProcedureHandle;
use crate::service_hardware::ServiceHardware;

/// The control thread's observers: status for the supervisor, telemetry for the log.
pub struct Observers {
    /// The status the supervisor reads.
    pub status: StatusPublisher,
    /// The session log's producer.
    pub telemetry: Option<TelemetryProducer>,
    /// The thimble state for the colour thread.
    pub thimble: Option<ThimblePublisher>,
    /// The thimble state for the scene's vision thread.
    pub vision_thimble: Option<ThimblePublisher>,
    /// The live view's copy of the status.
    pub live: Option<StatusPublisher>,
    /// The live view's calibrations (a re-initialization moves the guides it draws).
    pub live_calibrations: Option<rtrb::Producer<CalibrationInForce>>,
}

impl CycleObserver for Observers {
    fn observe(
        &mut self,
        record: &videt_runtime::cycle::CycleRecord,
        window: &videt_runtime::control_loop::WindowStats,
    ) {
        self.status.observe(record, window);
        if let Some(t) = self.telemetry.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.thimble.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.vision_thimble.as_mut() {
            t.observe(record, window);
        }
        if let Some(t) = self.live.as_mut() {
            t.observe(record, window);
        }
    }
}

/// What the control thread runs.
pub struct ControlThread<H, F, C> {
    /// The hardware.
    pub hw: H,
    /// The surface feed.
    pub feed: F,
    /// The control cycle.
    pub cycle: C,
    /// The loop's rate, duration and overrun limit.
    pub settings: LoopSettings,
    /// The configuration (a procedure's, a re-initialized cycle's).
    pub config: Config,
    /// The observers of every period.
    pub observers: Observers,
    /// Commands from the control socket.
    pub commands: rtrb::Consumer<videt_runtime::control_loop::ControlCommand>,
    /// The procedures the socket hands over (`None`: this hardware runs none).
    pub procedures: Option<ProcedureHandle>,
    /// The stop flag.
    pub stop: Arc<AtomicBool>,
}

/// What the control thread ends with: the loop's report and statistics, or why it stopped
/// without one.
pub type ControlOutcome = Result<(LoopReport, LoopStats), String>;

/// Start the control thread at `priority` on `cpu`.
pub fn spawn<const N: usize, D, H, F>(
    thread: ControlThread<H, F, ControlCycle<N, D>>,
    priority: u8,
    cpu: Option<usize>,
) -> std::io::Result<std::thread::JoinHandle<ControlOutcome>>
where
    D: RuntimeDevice<N>,
    H: ServiceHardware<N>,
    F: SurfaceFeed + Send + 'static,
{
    std::thread::Builder::new()
        .name("videt-control".into())
        .spawn(move || {
            let report = rt::setup_control_thread(priority, cpu);
            for w in &report.warnings {
                warn!("{w}");
            }
            run(thread)
        })
}

/// The control thread's body: start the hardware, then run the loop, and each procedure handed
/// over, until the loop ends.
fn run<const N: usize, D, H, F>(thread: ControlThread<H, F, ControlCycle<N, D>>) -> ControlOutcome
where
    D: RuntimeDevice<N>,
    H: ServiceHardware<N>,
    F: SurfaceFeed,
{
    let ControlThread {
        mut hw,
        mut feed,
        mut cycle,
        settings,
        config,
        mut observers,
        mut commands,
        mut procedures,
        stop,
    } = thread;
    start_hardware(&mut hw).map_err(|e| e.to_string())?;
    if let Some(t) = observers.telemetry.as_mut() {
        t.calibration(cycle.cycle_count(), &CalibrationInForce::of(&cycle));
    }
    let mut stats = LoopStats::default();
    let mut loop_control = LoopControl {
        stop: &stop,
        commands: Some(&mut commands),
    };
    let outcome = std::panic::catch_unwind(AssertUnwindSafe(|| {
        let started = hw.now();
        loop {
            // A hand-over restarts the loop: what is left of --duration.
            let mut settings = settings;
            settings.duration_ns = settings
                .duration_ns
                .map(|d| d.saturating_sub(hw.now().nanos_since(started)).max(1));
            let report = run_control_loop(
                &mut hw,
                &mut feed,
                &mut cycle,
                &settings,
                &mut loop_control,
                &mut observers,
                &mut stats,
            );
            let Some(handle) = procedures.as_mut().filter(|_| report.handed_over) else {
                if report.handed_over {
                    // A hand-over with no procedure to take it: power off as the loop does
                    // when it ends on its own.
                    let _ = hw.disable();
                    let _ = hw.deactivate();
                }
                break report;
            };
            // Procedure mode: same thread, same priority, same period.
            let Some(end) = hw.run_procedure(
                handle,
                &config,
                &mut observers,
                cycle.cycle_count(),
                cycle.wire_zero(),
                cycle.safety_state(),
            ) else {
                let _ = hw.disable();
                let _ = hw.deactivate();
                break report;
            };
            let next_cycle = end.next_cycle;
            match end
                .recalibration
                .and_then(|r| D::from_base_triangle(r.rig).map(|device| (device, r.wire_zero)))
            {
                Some((device, wire_zero)) => {
                    cycle =
                        videt_runtime::setup::control_cycle_for(&config, device, wire_zero, true);
                    cycle.set_cycle_count(next_cycle);
                    let calibration = CalibrationInForce::of(&cycle);
                    if let Some(t) = observers.telemetry.as_mut() {
                        t.calibration(next_cycle, &calibration);
                    }
                    if let Some(p) = observers.live_calibrations.as_mut() {
                        let _ = p.push(calibration);
                    }
                }
                None => {
                    cycle.restart();
                    cycle.set_cycle_count(next_cycle);
                }
            }
            if let Some(state) = end.trip {
                // A rig found not as configured renders nothing until the service restarts
                // with its configuration fixed.
                cycle.trip(state);
            }
        }
    }));
    match outcome {
        Ok(report) => Ok((report, stats)),
        Err(_) => {
            // Safe state: power off (the drives also stop by themselves when the host goes
            // silent).
            let _ = hw.disable();
            let _ = hw.deactivate();
            Err("the control loop panicked; drives powered off".to_string())
        }
    }
}
