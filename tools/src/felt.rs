//! The felt-force measure of a session (`docs/felt-force.md`): over the control periods of a
//! log (or of its replay), how far the rendered force went beyond what was asked, and the jolts.
//!
//! A period records the contact force `f_e`, the rendered force and the thimble's position;
//! what the algorithm added (its field, or the free-space pull) and the floor's pull `|V t_min|`
//! are computed back from the configuration and the calibration in force, with the same device
//! code the service ran.

use videt_control::{
    ControlStep, FeltPeriod, FeltTally, ForceSettings, SafetyState, Vec3, WireDevice,
};
use videt_rt_config::Config;
use videt_runtime::cycle::CycleRecord;
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::telemetry::Log;

/// The measure over `records` (the log's own, or a replay's, with their indices into
/// `log.records` for the calibration in force) under `config`. Periods of the procedures
/// (auto-initialization, wire replacement) are not the control cycle's and are skipped.
pub fn felt_report<'a>(
    log: &Log,
    config: &Config,
    records: impl Iterator<Item = (usize, &'a CycleRecord)>,
) -> Result<FeltTally, String> {
    match config.rig.device.as_str() {
        "planar2" => tally::<2, videt_control::PlanarDevice>(log, config, records),
        "polar1" => tally::<1, videt_control::PolarDevice>(log, config, records),
        "wireman3" | "" => tally::<3, videt_control::Rig3>(log, config, records),
        other => Err(format!(
            "rig.device = {other:?}: no session of it is recorded"
        )),
    }
}

fn tally<'a, const N: usize, D: RuntimeDevice<N>>(
    log: &Log,
    config: &Config,
    records: impl Iterator<Item = (usize, &'a CycleRecord)>,
) -> Result<FeltTally, String> {
    let mut tally = FeltTally::new();
    let mut calibrations = log.calibrations.iter().peekable();
    let mut step = None;
    for (i, record) in records {
        while let Some(c) = calibrations.next_if(|c| c.before_record <= i) {
            let (device, _zero) = c.calibration.device::<N, D>()?;
            step = Some(videt_runtime::setup::control_step_for(config, device));
        }
        if let Some(period) = step.as_ref().and_then(|s| felt_period(s, record)) {
            tally.add(&period);
        }
    }
    Ok(tally)
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
