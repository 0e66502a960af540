//! The digital twin in real time: the system clock paces the loop and drives the twin's physics.
//!
//! The physics catches up with the clock when the drives are read (as a bus exchange brings a
//! real device's state up to date), not inside the sleep: the loop's wake-up latency then
//! measures the operating system alone, and the physics cost shows in the compute time.

use videt_control::WireDevice;
use videt_hal::{
    AngleSensors, Clock, DriveSample, EStop, ErrorType, Lifecycle, LifecycleState, MonoTime,
    TensionSensors, WireDrives,
};
use videt_sim::{ClockMode, Twin, TwinError};

use videt_runtime::rt::SystemClock;

/// A [`Twin`] whose time is the system's monotonic clock (from the moment it was wrapped).
#[derive(Debug)]
pub struct RealTimeTwin<const N: usize, D: WireDevice<N>> {
    twin: Twin<N, D>,
    clock: SystemClock,
    origin: MonoTime,
}

impl<const N: usize, D: WireDevice<N>> RealTimeTwin<N, D> {
    /// Wrap a twin; its simulated time follows the system clock from now on.
    pub fn new(mut twin: Twin<N, D>) -> RealTimeTwin<N, D> {
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
    pub fn twin(&self) -> &Twin<N, D> {
        &self.twin
    }
    /// The twin, mutably.
    pub fn twin_mut(&mut self) -> &mut Twin<N, D> {
        &mut self.twin
    }
}

impl<const N: usize, D: WireDevice<N>> ErrorType for RealTimeTwin<N, D> {
    type Error = TwinError;
}

impl<const N: usize, D: WireDevice<N>> Lifecycle for RealTimeTwin<N, D> {
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

impl<const N: usize, D: WireDevice<N>> WireDrives<N> for RealTimeTwin<N, D> {
    fn enable(&mut self) -> Result<(), TwinError> {
        self.twin.enable()
    }
    fn disable(&mut self) -> Result<(), TwinError> {
        self.twin.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), TwinError> {
        let now = self.now();
        self.twin.advance_to(now);
        self.twin.read_drives(out)
    }
    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), TwinError> {
        self.twin.write_torques(torque_nm)
    }
}

impl<const N: usize, D: WireDevice<N>> TensionSensors<N> for RealTimeTwin<N, D> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), TwinError> {
        self.twin.read_tensions(out_n)
    }
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], TwinError> {
        self.twin.read_fresh_tensions(out_n)
    }
}

impl<const N: usize, D: WireDevice<N>> AngleSensors for RealTimeTwin<N, D> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), TwinError> {
        self.twin.read_angles(out_rad)
    }
}

impl<const N: usize, D: WireDevice<N>> EStop for RealTimeTwin<N, D> {
    fn is_pressed(&mut self) -> Result<bool, TwinError> {
        self.twin.is_pressed()
    }
    fn reset(&mut self) -> Result<(), TwinError> {
        self.twin.reset()
    }
}

impl<const N: usize, D: WireDevice<N>> Clock for RealTimeTwin<N, D> {
    fn now(&self) -> MonoTime {
        MonoTime(self.clock.now().0.saturating_sub(self.origin.0))
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.clock.sleep_until(deadline.add_nanos(self.origin.0));
    }
}
