//! The digital twin in real time: the system clock paces the loop and drives the twin's physics.
//!
//! The physics catches up with the clock when the drives are read (as a bus exchange brings a
//! real device's state up to date), not inside the sleep: the loop's wake-up latency then
//! measures the operating system alone, and the physics cost shows in the compute time.

use videt_hal::{
    Clock, DriveSample, EStop, ErrorType, Lifecycle, LifecycleState, MonoTime, TensionSensors,
    WireDrives, WIRES,
};
use videt_sim::{ClockMode, Twin, TwinError};

use crate::rt::SystemClock;

/// A [`Twin`] whose time is the system's monotonic clock (from the moment it was wrapped).
#[derive(Debug)]
pub struct RealTimeTwin {
    twin: Twin,
    clock: SystemClock,
    origin: MonoTime,
}

impl RealTimeTwin {
    /// Wrap a twin; its simulated time follows the system clock from now on.
    pub fn new(mut twin: Twin) -> RealTimeTwin {
        twin.set_clock_mode(ClockMode::External);
        let clock = SystemClock;
        let origin = MonoTime(clock.now().0.saturating_sub(twin.sim_time().0));
        RealTimeTwin {
            twin,
            clock,
            origin,
        }
    }
    /// The twin.
    pub fn twin(&self) -> &Twin {
        &self.twin
    }
    /// The twin, mutably.
    pub fn twin_mut(&mut self) -> &mut Twin {
        &mut self.twin
    }
}

impl ErrorType for RealTimeTwin {
    type Error = TwinError;
}

impl Lifecycle for RealTimeTwin {
    fn configure(&mut self) -> Result<(), TwinError> {
        self.twin.configure()
    }
    fn activate(&mut self) -> Result<(), TwinError> {
        self.twin.activate()
    }
    fn deactivate(&mut self) -> Result<(), TwinError> {
        self.twin.deactivate()
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.twin.lifecycle_state()
    }
}

impl WireDrives for RealTimeTwin {
    fn enable(&mut self) -> Result<(), TwinError> {
        self.twin.enable()
    }
    fn disable(&mut self) -> Result<(), TwinError> {
        self.twin.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; WIRES]) -> Result<(), TwinError> {
        let now = self.now();
        self.twin.advance_to(now);
        self.twin.read_drives(out)
    }
    fn write_torques(&mut self, torque_nm: &[f64; WIRES]) -> Result<(), TwinError> {
        self.twin.write_torques(torque_nm)
    }
}

impl TensionSensors for RealTimeTwin {
    fn read_tensions(&mut self, out_n: &mut [f64; WIRES]) -> Result<(), TwinError> {
        self.twin.read_tensions(out_n)
    }
    fn read_fresh_tensions(
        &mut self,
        out_n: &mut [f64; WIRES],
    ) -> Result<[bool; WIRES], TwinError> {
        self.twin.read_fresh_tensions(out_n)
    }
}

impl EStop for RealTimeTwin {
    fn is_pressed(&mut self) -> Result<bool, TwinError> {
        self.twin.is_pressed()
    }
    fn reset(&mut self) -> Result<(), TwinError> {
        self.twin.reset()
    }
}

impl Clock for RealTimeTwin {
    fn now(&self) -> MonoTime {
        MonoTime(self.clock.now().0.saturating_sub(self.origin.0))
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.clock.sleep_until(deadline.add_nanos(self.origin.0));
    }
}
