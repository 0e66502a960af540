//! What the service needs of its hardware beyond the HAL capabilities: the procedures
//! (auto-initialization, tension calibration, wire replacement) and the twin's fault injection,
//! where the hardware has them; implemented here for every hardware the assembly opens.

use videt_assembly::can_twin::CanTwin;
use videt_assembly::hardware::DeviceHardware;
use videt_assembly::sim_faults::SimFaultPort;
use videt_assembly::twin_rt::RealTimeTwin;
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::{PlanarDevice, PolarDevice, Rig3};
use videt_hal::{AngleSensors, Clock, EStop, Lifecycle, TensionSensors, WireDrives};
use videt_runtime::control_loop::CycleObserver;
use videt_runtime::cycle::WireZero;
use videt_runtime::WIREMAN_WIRES;

use crate::init::corrected::CorrectedTensions;
use crate::init::remote::{ProcedureDevice, ProcedureEnd, ProcedureHandle};

/// The service's hardware: the HAL capabilities of an `N`-wire device, and what the service
/// can do with it beyond the control cycle.
pub trait ServiceHardware<const N: usize>:
    Lifecycle + WireDrives<N> + TensionSensors<N> + EStop + AngleSensors + Clock + Send + 'static
{
    /// The hardware is a digital twin (the procedures' technician is then simulated).
    fn is_twin(&self) -> bool;

    /// The handles that inject faults into a running twin; `None` on a device (and on twins
    /// without them).
    fn sim_faults(&mut self) -> Option<SimFaultPort> {
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
    ) -> Option<ProcedureEnd> {
        None
    }
}

/// The [`ServiceHardware`] of a WireMan whose hardware runs the procedures: `$is_twin` tells
/// from the hardware whether it is a twin; `[generics]` are the impl's, for a generic wrapper.
macro_rules! wireman_service_hardware {
    ($ty:ty, $is_twin:expr $(, [$($generics:tt)*])?) => {
        impl $(<$($generics)*>)? ServiceHardware<3> for $ty {
            fn is_twin(&self) -> bool {
                ($is_twin)(self)
            }
            fn sim_faults(&mut self) -> Option<SimFaultPort> {
                ProcedureDevice::sim_faults(self)
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
            ) -> Option<ProcedureEnd> {
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
    };
}

wireman_service_hardware!(videt_assembly::WiremanTwin, |_| true);
wireman_service_hardware!(RealTimeTwin<3, Rig3>, |_| true);
wireman_service_hardware!(CanTwin<3, RealTimeTwin<3, Rig3>>, |_| true);
// Corrected tension readings are the wrapped hardware's, and so is being a twin.
wireman_service_hardware!(
    CorrectedTensions<H>,
    |hw: &CorrectedTensions<H>| hw.inner().is_twin(),
    [H: ServiceHardware<3> + ProcedureDevice]
);

/// The [`ServiceHardware`] of the twin of a device without procedures, behind CiA 402 drives
/// on the simulated CAN bus.
macro_rules! can_twin_service_hardware {
    ($n:literal, $device:ty) => {
        impl ServiceHardware<$n> for CanTwin<$n, RealTimeTwin<$n, $device>> {
            fn is_twin(&self) -> bool {
                true
            }
            fn sim_faults(&mut self) -> Option<SimFaultPort> {
                Some(CanTwin::sim_faults(self))
            }
        }
    };
}

can_twin_service_hardware!(2, PlanarDevice);
can_twin_service_hardware!(1, PolarDevice);

/// The [`ServiceHardware`] of the twin of a device without procedures.
macro_rules! twin_service_hardware {
    ($n:literal, $device:ty) => {
        impl ServiceHardware<$n> for RealTimeTwin<$n, $device> {
            fn is_twin(&self) -> bool {
                true
            }
            fn sim_faults(&mut self) -> Option<SimFaultPort> {
                Some(SimFaultPort {
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

/// The [`ServiceHardware`] of a device without procedures behind the tension correction the
/// service runs every device through: the wrapped hardware's.
macro_rules! corrected_service_hardware {
    ($n:literal, $ty:ty) => {
        impl ServiceHardware<$n> for CorrectedTensions<$ty> {
            fn is_twin(&self) -> bool {
                self.inner().is_twin()
            }
            fn sim_faults(&mut self) -> Option<SimFaultPort> {
                self.inner_mut().sim_faults()
            }
        }
    };
}

corrected_service_hardware!(2, RealTimeTwin<2, PlanarDevice>);
corrected_service_hardware!(2, CanTwin<2, RealTimeTwin<2, PlanarDevice>>);
corrected_service_hardware!(1, RealTimeTwin<1, PolarDevice>);
corrected_service_hardware!(1, CanTwin<1, RealTimeTwin<1, PolarDevice>>);

#[cfg(target_os = "linux")]
wireman_service_hardware!(videt_assembly::hardware::LinuxDevice, |_| false);

/// Procedures (`videt init`, wire replacement) run on the device with a real technician.
impl<D: WireDrives<WIREMAN_WIRES>, T: TensionSensors<WIREMAN_WIRES>, E: EStop> ProcedureDevice
    for DeviceHardware<D, T, E>
{
}
