//! Where a motor-driving subcommand runs when no service answers: on the twin with its simulated
//! technician (`--sim`), or on the device this tool opens itself, with the technician at the
//! terminal. Both take the motors lock first, start the hardware, run the job and leave the
//! drives disabled.

use std::sync::atomic::AtomicBool;

use videt_config::Config;
use videt_hal::Lifecycle;

use super::device::{stop_on_signals, DeviceArgs, Exit};
use videt_service::init::commission::CommissionTechnician;
use videt_service::init::remote::ProcedureDevice;
use videt_service::init::runner::Runner;
use videt_service::init::session::{self, Technician};
use videt_service::init::tension::TensionTechnician;
use videt_service::init::twin::{rest_twin, SimTechnician, TwinSetup};

/// Exit code when the device cannot be opened or started (the procedures' "the hardware would
/// not start").
pub const EXIT_HARDWARE_START: u8 = 22;

/// What a subcommand does once the hardware is up, on whichever hardware and technician.
pub trait MotorJob {
    /// What the job gives back.
    type Output;

    /// Run on started hardware; `source` is `twin` or `device`.
    fn run<H, T>(
        &mut self,
        hw: &mut H,
        tech: &mut T,
        runner: &mut Runner,
        source: &'static str,
        stop: &AtomicBool,
    ) -> Result<Self::Output, Exit>
    where
        H: ProcedureDevice,
        T: Technician<H> + TensionTechnician<H> + CommissionTechnician<H>;

    /// The device's drive set is opened: `report` fills with each drive's identity when it
    /// starts (not called on the twin, which has no CANopen drives).
    fn drives_opened(&mut self, _report: videt_drivers::cia402::SharedStartupReport) {}
}

/// Take the motors lock, then run `job` on the twin of `setup` (`--sim`) or on the device of
/// `config`; `runner` is prepared by the caller (its tension correction). The drives are
/// disabled and deactivated afterwards, whatever the job's outcome.
pub fn on_motors<J: MotorJob>(
    device: &DeviceArgs,
    config: &Config,
    setup: &TwinSetup,
    mut runner: Runner,
    job: &mut J,
) -> Result<J::Output, Exit> {
    let _lock = device.lock_motors(config)?;
    let stop = stop_on_signals();
    if device.sim {
        let mut twin = rest_twin(config, setup);
        let mut tech = SimTechnician::new(setup);
        tech.echo = true;
        return run_started(&mut twin, &mut tech, &mut runner, "twin", &stop, job);
    }
    on_device(device, config, runner, &stop, job)
}

#[cfg(target_os = "linux")]
fn on_device<J: MotorJob>(
    device: &DeviceArgs,
    config: &Config,
    mut runner: Runner,
    stop: &AtomicBool,
    job: &mut J,
) -> Result<J::Output, Exit> {
    let mut hw = videt_assembly::hardware::open_device(config)
        .map_err(|e| Exit::new(EXIT_HARDWARE_START, "device", format!("device: {e}")))?;
    // The procedure's loop paces the drives: it gets the control thread's real-time settings
    // when allowed (a warning otherwise: it still runs, with more jitter).
    let realtime = &config.realtime;
    if realtime.lock_memory {
        if let Err(e) = videt_runtime::rt::lock_memory() {
            eprintln!("videt: memory not locked ({e}): page faults may delay the loop");
        }
    }
    let cpu = usize::try_from(realtime.control_cpu).ok();
    let rt = videt_runtime::rt::setup_control_thread(realtime.control_priority, cpu);
    for warning in &rt.warnings {
        eprintln!("videt: {warning}");
    }
    job.drives_opened(hw.drives_mut().startup_report());
    let mut tech = super::device::TerminalTechnician::new(device.yes, device.steps_from_stdin);
    run_started(&mut hw, &mut tech, &mut runner, "device", stop, job)
}

#[cfg(not(target_os = "linux"))]
fn on_device<J: MotorJob>(
    device: &DeviceArgs,
    _config: &Config,
    _runner: Runner,
    _stop: &AtomicBool,
    _job: &mut J,
) -> Result<J::Output, Exit> {
    Err(device.no_backend())
}

fn run_started<H, T, J>(
    hw: &mut H,
    tech: &mut T,
    runner: &mut Runner,
    source: &'static str,
    stop: &AtomicBool,
    job: &mut J,
) -> Result<J::Output, Exit>
where
    H: ProcedureDevice + Lifecycle,
    T: Technician<H> + TensionTechnician<H> + CommissionTechnician<H>,
    J: MotorJob,
{
    let result = session::start(hw)
        .map_err(|e| Exit::new(e.exit_code(), e.name(), e.to_string()))
        .and_then(|()| job.run(hw, tech, runner, source, stop));
    let _ = hw.disable();
    let _ = hw.deactivate();
    result
}
