//! The felt-force measure of a session (`docs/felt-force.md`): over the control periods of a
//! log (or of its replay), how far the rendered force went beyond what was asked, and the jolts.
//!
//! A period records the contact force `f_e`, the rendered force and the thimble's position;
//! what the algorithm added (its field, or the free-space pull) and the floor's pull `|V t_min|`
//! are computed back from the configuration and the calibration in force, with the same device
//! code the service ran.

use videt_config::Config;
use videt_control::{
    ControlStep, FeltPeriod, FeltTally, ForceSettings, SafetyState, Vec3, WireDevice,
};
use videt_runtime::cycle::CycleRecord;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::telemetry::{CalibrationInForce, Log};

/// The measure over `records` (the log's own, or a replay's, with their indices into
/// `log.records` for the calibration in force) under `config`. Periods of the procedures
/// (auto-initialization, wire replacement) are not the control cycle's and are skipped.
pub fn felt_report<'a>(
    log: &Log,
    config: &Config,
    records: impl Iterator<Item = (usize, &'a CycleRecord)>,
) -> Result<FeltTally, String> {
    let mut counter = FeltCounter::new(config)?;
    let mut calibrations = log.calibrations.iter().peekable();
    for (i, record) in records {
        while let Some(c) = calibrations.next_if(|c| c.before_record <= i) {
            counter.calibration(&c.calibration);
        }
        counter.period(record);
    }
    counter.finish()
}

/// The measure taken as a log is read: each calibration as it comes, then the periods it
/// applies to.
pub struct FeltCounter {
    config: Config,
    step: DeviceStep,
    tally: FeltTally,
    error: Option<String>,
}

/// The control step of the calibration in force, of the session's device.
enum DeviceStep {
    Wireman(Option<ControlStep<3, videt_control::Rig3>>),
    Planar(Option<ControlStep<2, videt_control::PlanarDevice>>),
    Polar(Option<ControlStep<1, videt_control::PolarDevice>>),
}

impl FeltCounter {
    /// A counter for the sessions of `config`'s device.
    pub fn new(config: &Config) -> Result<FeltCounter, String> {
        let step = match config.rig.device.as_str() {
            "planar2" => DeviceStep::Planar(None),
            "polar1" => DeviceStep::Polar(None),
            "wireman3" | "" => DeviceStep::Wireman(None),
            other => {
                return Err(format!(
                    "rig.device = {other:?}: no session of it is recorded"
                ))
            }
        };
        Ok(FeltCounter {
            config: config.clone(),
            step,
            tally: FeltTally::new(),
            error: None,
        })
    }

    /// The calibration in force from the next period on.
    pub fn calibration(&mut self, calibration: &CalibrationInForce) {
        fn step_of<const N: usize, D: RuntimeDevice<N>>(
            config: &Config,
            calibration: &CalibrationInForce,
        ) -> Result<ControlStep<N, D>, String> {
            let (device, _zero) = calibration.device::<N, D>()?;
            Ok(videt_runtime::setup::control_step_for(config, device))
        }
        let config = &self.config;
        let made = match &mut self.step {
            DeviceStep::Wireman(s) => step_of(config, calibration).map(|n| *s = Some(n)),
            DeviceStep::Planar(s) => step_of(config, calibration).map(|n| *s = Some(n)),
            DeviceStep::Polar(s) => step_of(config, calibration).map(|n| *s = Some(n)),
        };
        if let Err(e) = made {
            self.error.get_or_insert(e);
        }
    }

    /// One period of the log.
    pub fn period(&mut self, record: &CycleRecord) {
        let period = match &self.step {
            DeviceStep::Wireman(s) => s.as_ref().and_then(|s| felt_period(s, record)),
            DeviceStep::Planar(s) => s.as_ref().and_then(|s| felt_period(s, record)),
            DeviceStep::Polar(s) => s.as_ref().and_then(|s| felt_period(s, record)),
        };
        if let Some(period) = period {
            self.tally.add(&period);
        }
    }

    /// The measure, or the first calibration that could not be used.
    pub fn finish(self) -> Result<FeltTally, String> {
        match self.error {
            Some(e) => Err(e),
            None => Ok(self.tally),
        }
    }
}

/// A control period as the measure sees it, with what `step`'s algorithm added and the floor's
/// pull computed back from the recorded position (`None` for a procedure's period).
pub fn felt_period<const N: usize, D: WireDevice<N>>(
    step: &ControlStep<N, D>,
    record: &CycleRecord,
) -> Option<FeltPeriod> {
    if !record.inputs.from_cycle {
        return None;
    }
    let params = step.params();
    let settings = ForceSettings {
        algorithm: params.algorithm,
        limits: params.limits,
        field: params.field,
        free_space_field_n: params.free_space_field_n,
    };
    let device = step.rig();
    let position = Vec3::from(record.position_m);
    let desired = Vec3::from(record.desired_force_n);
    // Out of the normal state every wire is held at t_min: nothing is added.
    let field = if record.safety == SafetyState::Normal {
        device
            .forces(
                &position,
                &desired,
                record.in_contact,
                record.force_scale.clamp(0.0, 1.0),
                &settings,
            )
            .map_or_else(Vec3::zeros, |f| f.field_force_n)
    } else {
        Vec3::zeros()
    };
    Some(FeltPeriod {
        cycle: record.cycle,
        desired_n: desired,
        field_n: field,
        rendered_n: Vec3::from(record.rendered_force_n),
        floor_pull_n: device
            .force_of(&position, &[settings.limits.t_min_n; N])
            .norm(),
    })
}
