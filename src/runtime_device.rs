//! The configured device as the service runs it: the wire count is a const generic chosen once
//! at start-up (`videtd` matches `rig.device` and calls one monomorphized service), never a
//! dispatch inside the control period.
//!
//! - [`RuntimeDevice`]: what the runtime needs of a device beyond its control step (how its
//!   geometry is recorded in the session log, whether the base-triangle calibration applies).
//! - [`ServiceHardware`]: what the service needs of its hardware beyond the HAL capabilities:
//!   the procedures (auto-initialization, tension calibration, wire replacement) and the twin's
//!   fault injection, where the hardware has them.

use videt_control::autoinit::BASE_WIRES;
use videt_control::safety::SafetyState;
use videt_control::{PlanarDevice, PolarDevice, Rig3, RigPlanar, Vec3, WireDevice};
use videt_hal::{AngleSensors, Clock, EStop, Lifecycle, TensionSensors, WireDrives};
use videt_rt_config::Config;

use crate::control_loop::CycleObserver;
use crate::cycle::{WireZero, LOG_WIRE_SLOTS};
use crate::init::remote::{ProcedureHandle, Recalibration};

/// A device the service can run.
pub trait RuntimeDevice<const N: usize>: WireDevice<N> {
    /// The device's guide points as the session log records them, `[x, y, z]` metres, one per
    /// wire (the remaining slots zero).
    fn logged_guides_m(&self) -> [[f64; 3]; LOG_WIRE_SLOTS];

    /// The device back from recorded guide points.
    fn from_logged_guides(guides_m: &[[f64; 3]; LOG_WIRE_SLOTS]) -> Result<Self, String>;

    /// The device after an auto-initialization measured the base triangle (`None`: the
    /// procedure does not apply to this device).
    fn from_base_triangle(rig: Rig3) -> Option<Self>;
}

impl RuntimeDevice<BASE_WIRES> for Rig3 {
    fn logged_guides_m(&self) -> [[f64; 3]; LOG_WIRE_SLOTS] {
        let g = self.guides_m();
        core::array::from_fn(|i| [g[i].x, g[i].y, g[i].z])
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; LOG_WIRE_SLOTS]) -> Result<Self, String> {
        Rig3::new(guides_m.map(|g| Vec3::new(g[0], g[1], g[2])))
            .map_err(|e| format!("recorded rig geometry: {e}"))
    }

    fn from_base_triangle(rig: Rig3) -> Option<Self> {
        Some(rig)
    }
}

impl RuntimeDevice<2> for PlanarDevice {
    fn logged_guides_m(&self) -> [[f64; 3]; LOG_WIRE_SLOTS] {
        let [x0, x1] = self.rig().guides_x_m();
        [[x0, 0.0, 0.0], [x1, 0.0, 0.0], [0.0; 3]]
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; LOG_WIRE_SLOTS]) -> Result<Self, String> {
        RigPlanar::new([guides_m[0][0], guides_m[1][0]])
            .map(PlanarDevice::new)
            .map_err(|e| format!("recorded planar geometry: {e}"))
    }

    fn from_base_triangle(_rig: Rig3) -> Option<Self> {
        None
    }
}

impl RuntimeDevice<1> for PolarDevice {
    fn logged_guides_m(&self) -> [[f64; 3]; LOG_WIRE_SLOTS] {
        let g = self.guide_m();
        [[g.x, g.y, g.z], [0.0; 3], [0.0; 3]]
    }

    fn from_logged_guides(guides_m: &[[f64; 3]; LOG_WIRE_SLOTS]) -> Result<Self, String> {
        let g = guides_m[0];
        PolarDevice::new(Vec3::new(g[0], g[1], g[2]))
            .map_err(|e| format!("recorded one-wire geometry: {e}"))
    }

    fn from_base_triangle(_rig: Rig3) -> Option<Self> {
        None
    }
}

/// What a procedure run through the control socket left: a new calibration or none, and the
/// next period's number.
pub type ProcedureOutcome = (Option<Recalibration>, u64);

/// The service's hardware: the HAL capabilities of an `N`-wire device, and what the service
/// can do with it beyond the control cycle.
pub trait ServiceHardware<const N: usize>:
    Lifecycle + WireDrives<N> + TensionSensors<N> + EStop + AngleSensors + Clock + Send + 'static
{
    /// The hardware is a digital twin (the procedures' technician is then simulated).
    fn is_twin(&self) -> bool;

    /// The handles that inject faults into a running twin; `None` on a device (and on twins
    /// without them).
    fn sim_faults(&mut self) -> Option<crate::sim_faults::SimFaultPort> {
        None
    }

    /// Whether procedures (auto-initialization, tension calibration, wire replacement) run on
    /// this hardware: the WireMan's only.
    fn runs_procedures(&self) -> bool {
        false
    }

    /// Run the procedure the control socket handed over, in the control thread; `None` when this
    /// hardware runs none.
    #[allow(clippy::too_many_arguments)]
    fn run_procedure(
        &mut self,
        _handle: &mut ProcedureHandle,
        _config: &Config,
        _observer: &mut dyn CycleObserver,
        _first_cycle: u64,
        _wire_zero: WireZero,
        _safety: SafetyState,
    ) -> Option<ProcedureOutcome> {
        None
    }
}

/// The [`ServiceHardware`] of a WireMan whose hardware runs the procedures.
macro_rules! wireman_service_hardware {
    ($ty:ty, $twin:expr $(, $generics:tt)*) => {
        impl $($generics)* $crate::runtime_device::ServiceHardware<3> for $ty {
            fn is_twin(&self) -> bool {
                $twin
            }
            fn sim_faults(&mut self) -> Option<$crate::sim_faults::SimFaultPort> {
                $crate::init::remote::ProcedureDevice::sim_faults(self)
            }
            fn runs_procedures(&self) -> bool {
                true
            }
            fn run_procedure(
                &mut self,
                handle: &mut $crate::init::remote::ProcedureHandle,
                config: &videt_rt_config::Config,
                observer: &mut dyn $crate::control_loop::CycleObserver,
                first_cycle: u64,
                wire_zero: $crate::cycle::WireZero,
                safety: videt_control::safety::SafetyState,
            ) -> Option<$crate::runtime_device::ProcedureOutcome> {
                Some($crate::init::remote::run_procedure(
                    self,
                    handle,
                    config,
                    observer,
                    first_cycle,
                    wire_zero,
                    safety,
                ))
            }
        }
    };
}
pub(crate) use wireman_service_hardware;

wireman_service_hardware!(crate::WiremanTwin, true);
wireman_service_hardware!(crate::twin_rt::RealTimeTwin<3, Rig3>, true);
wireman_service_hardware!(
    crate::can_twin::CanTwin<3, crate::twin_rt::RealTimeTwin<3, Rig3>>,
    true
);

impl<H> ServiceHardware<3> for crate::init::corrected::CorrectedTensions<H>
where
    H: ServiceHardware<3> + crate::init::remote::ProcedureDevice,
{
    fn is_twin(&self) -> bool {
        self.inner().is_twin()
    }
    fn sim_faults(&mut self) -> Option<crate::sim_faults::SimFaultPort> {
        crate::init::remote::ProcedureDevice::sim_faults(self)
    }
    fn runs_procedures(&self) -> bool {
        true
    }
    fn run_procedure(
        &mut self,
        handle: &mut ProcedureHandle,
        config: &Config,
        observer: &mut dyn CycleObserver,
        first_cycle: u64,
        wire_zero: WireZero,
        safety: SafetyState,
    ) -> Option<ProcedureOutcome> {
        Some(crate::init::remote::run_procedure(
            self,
            handle,
            config,
            observer,
            first_cycle,
            wire_zero,
            safety,
        ))
    }
}

/// The [`ServiceHardware`] of the twin of a device without procedures, behind CiA 402 drives
/// on the simulated CAN bus.
macro_rules! can_twin_service_hardware {
    ($n:literal, $device:ty) => {
        impl ServiceHardware<$n>
            for crate::can_twin::CanTwin<$n, crate::twin_rt::RealTimeTwin<$n, $device>>
        {
            fn is_twin(&self) -> bool {
                true
            }
            fn sim_faults(&mut self) -> Option<crate::sim_faults::SimFaultPort> {
                Some(crate::can_twin::CanTwin::sim_faults(self))
            }
        }
    };
}

can_twin_service_hardware!(2, PlanarDevice);
can_twin_service_hardware!(1, PolarDevice);

/// The [`ServiceHardware`] of the twin of a device without procedures.
macro_rules! twin_service_hardware {
    ($n:literal, $device:ty) => {
        impl ServiceHardware<$n> for crate::twin_rt::RealTimeTwin<$n, $device> {
            fn is_twin(&self) -> bool {
                true
            }
            fn sim_faults(&mut self) -> Option<crate::sim_faults::SimFaultPort> {
                Some(crate::sim_faults::SimFaultPort {
                    twin: self.twin().fault_inbox(),
                    bus: None,
                    drives: Vec::new(),
                    vision_stall: None,
                    wires: $n,
                })
            }
        }
    };
}

twin_service_hardware!(2, PlanarDevice);
twin_service_hardware!(1, PolarDevice);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_device_comes_back_from_its_log() {
        let rig = Rig3::new([
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.3, 0.0),
        ])
        .unwrap();
        assert_eq!(
            Rig3::from_logged_guides(&rig.logged_guides_m()).unwrap(),
            rig
        );
        let planar = PlanarDevice::paper_prototype();
        assert_eq!(
            PlanarDevice::from_logged_guides(&planar.logged_guides_m()).unwrap(),
            planar
        );
        let polar = PolarDevice::new(Vec3::new(0.1, 0.2, 0.0)).unwrap();
        assert_eq!(
            PolarDevice::from_logged_guides(&polar.logged_guides_m()).unwrap(),
            polar
        );
        assert!(PlanarDevice::from_logged_guides(&[[0.1, 0.0, 0.0]; 3]).is_err());
        assert!(PlanarDevice::from_base_triangle(rig).is_none());
        assert_eq!(Rig3::from_base_triangle(rig), Some(rig));
    }
}
