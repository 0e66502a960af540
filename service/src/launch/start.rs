//! The one start: every case (the device, the HAL twin, the CAN twin; every scene) runs the
//! service from here, its tension readings corrected by the strain-gauge calibration when the
//! plan found one, with the scene's feed, colour and links and the hardware's reports.

use std::process::ExitCode;

use videt_config::calibration::TensionCalibration;
use videt_runtime::cycle::ControlCycle;
use videt_runtime::runtime_device::RuntimeDevice;

use super::scene::Scene;
use crate::init::corrected::CorrectedTensions;
use crate::run::{run_service, HardwareReports, ServiceSettings};
use crate::service_hardware::ServiceHardware;

/// What every case starts the service with: the plan's settings and tension correction.
pub struct Starter {
    /// The service's settings, the configuration in force among them.
    pub settings: ServiceSettings,
    /// The strain-gauge calibration that corrects the tension readings, when the plan found one.
    pub tension_correction: Option<TensionCalibration>,
}

impl Starter {
    /// Run the service on `hw` with `scene` and `cycle` until it stops; the exit code.
    /// `description` is what runs, for the session log.
    pub fn start<const N: usize, D, H>(
        &self,
        hw: H,
        scene: Scene,
        cycle: ControlCycle<N, D>,
        description: String,
        reports: HardwareReports,
    ) -> ExitCode
    where
        D: RuntimeDevice<N>,
        CorrectedTensions<H>: ServiceHardware<N>,
    {
        let mut settings = self.settings.clone();
        settings.colour = scene.colour;
        settings.description = description;
        run_service(
            CorrectedTensions::new(hw, self.tension_correction.clone()),
            scene.feed,
            cycle,
            &settings,
            scene.links,
            reports,
        )
    }
}
