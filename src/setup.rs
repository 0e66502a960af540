//! Building the runtime's pieces from the configuration: rig, control step, cycle, and the
//! digital twin's demonstration scene.

use videt_control::safety::SafetyLimits;
use videt_control::{
    Algorithm, ControlParams, ControlStep, ForceField, ForceLimits, Plane, Rig3, RigError,
    TensionPiGains,
};
use videt_hal::Transmission;
use videt_rt_config::Config;
use videt_sim::{PlantParams, SensorModel, Twin, VirtualOperator};

use crate::cycle::{ControlCycle, CycleSettings, WireZero};

/// The transmission the configuration describes.
pub fn transmission(config: &Config) -> Transmission {
    let t = &config.transmission;
    Transmission {
        counts_per_motor_rev: t.counts_per_motor_rev,
        gear_ratio: t.gear_ratio,
        pulley_radius_m: t.pulley_radius_m,
        efficiency: t.efficiency,
    }
}

/// The rated torque (0x6076) of the twins' simulated drives, mN·m: the configured drive's
/// (`drives.rated_torque_nm`, from `drives.device_description` when the file gives it) to the
/// nearest mN·m, the unit of the twins' CiA 402 drives, and at least 1.
pub fn twin_rated_torque_mnm(config: &Config) -> u32 {
    whole_mnm(config.drives.rated_torque_nm)
}

/// A rated torque in N·m to the nearest mN·m (the unit of the twins' CiA 402 drives), at least 1.
pub fn whole_mnm(torque_nm: f64) -> u32 {
    (torque_nm * 1000.0).round().clamp(1.0, f64::from(u32::MAX)) as u32
}

/// One step of the twins' target torque (one per mille of [`twin_rated_torque_mnm`]), N·m:
/// the HAL twin's motors apply torque in these steps, as the CAN twin's drives do.
pub fn twin_torque_step_nm(config: &Config) -> f64 {
    f64::from(twin_rated_torque_mnm(config)) * 1e-6
}

/// The rig geometry of the configuration.
pub fn rig(config: &Config) -> Result<Rig3, RigError> {
    let g = &config.rig.guides_m;
    Rig3::new(core::array::from_fn(|i| {
        videt_control::Vec3::new(g[i][0], g[i][1], 0.0)
    }))
}

/// The control step for a rig.
pub fn control_step(config: &Config, rig: Rig3) -> ControlStep {
    let c = &config.control;
    let tr = transmission(config);
    let feedforward = tr.torque_for_tension(1.0);
    // The configuration was validated: the name is known.
    let algorithm = Algorithm::from_name(&c.algorithm).unwrap_or_default();
    // A sensor too slow for the configured gains runs them reduced when the configuration
    // allows it (a configuration that does not is refused before this).
    let gain_scale = crate::tension_budget::plan(config).map_or(1.0, |p| p.gain_scale());
    ControlStep::new(
        rig,
        ControlParams {
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
            algorithm,
            limits: ForceLimits {
                t_min_n: c.t_min_n,
                t_max_n: c.t_max_n,
            },
            pi: TensionPiGains {
                feedforward_nm_per_n: feedforward,
                kp_nm_per_n: gain_scale * c.tension_kp_nm_per_n,
                ki_nm_per_n_s: gain_scale * c.tension_ki_nm_per_n_s,
                torque_limit_nm: 1.25 * tr.torque_for_tension(c.t_max_n),
                speed_gain_nm_s_per_m: c.speed_gain_nm_s_per_m,
                slack_tension_n: 0.5 * c.t_min_n,
                takeup_speed_m_s: c.slack_takeup_speed_m_s,
                max_winding_speed_m_s: 0.75 * c.max_wire_speed_m_s,
            },
            field: ForceField::towards_frame(c.field_n),
            free_space_field_n: c.free_space_field_n,
        },
    )
}

/// The control cycle for a rig, with the encoder zero and whether the rig is calibrated.
pub fn control_cycle(
    config: &Config,
    rig: Rig3,
    wire_zero: WireZero,
    calibrated: bool,
) -> ControlCycle {
    let c = &config.control;
    ControlCycle::new(
        control_step(config, rig),
        SafetyLimits::for_device(c.t_min_n, c.t_max_n, c.max_wire_speed_m_s),
        CycleSettings {
            transmission: transmission(config),
            wire_zero,
            period_s: 1.0 / f64::from(c.rate_hz),
            ramp_s: c.ramp_down_s,
            calibrated,
            surface_max_age_s: config.vision.surface_max_age_s,
            surface_fade_s: config.vision.surface_fade_s,
        },
    )
}

/// The twin's demonstration scene: a wall in front of the frame, and a virtual operator who
/// touches it, slides along it and comes back, over and over.
#[derive(Debug)]
pub struct DemoScene {
    /// The twin, with the thimble in front of the frame's centre.
    pub twin: Twin,
    /// The wall (solid beyond `z = wall_z_m`, outward normal towards the user, `-z`).
    pub wall: Plane,
    /// Where the wall is, metres.
    pub wall_z_m: f64,
}

/// Build the demonstration scene for the configured rig (the twin's guides are the configured
/// ones: on the twin the configuration is the truth; its motors apply torque in the configured
/// drive's steps, [`twin_torque_step_nm`]).
pub fn demo_scene(config: &Config, sensor_seed: u64) -> DemoScene {
    let g = &config.rig.guides_m;
    let mut params = PlantParams::paper_default();
    params.guides_m = core::array::from_fn(|i| videt_sim::Vec3::new(g[i][0], g[i][1], 0.0));
    params.transmission = transmission(config);
    let centre = (params.guides_m[0] + params.guides_m[1] + params.guides_m[2]) / 3.0;
    let start = centre + videt_sim::Vec3::new(0.0, 0.0, 0.30);
    let wall_z_m = CHECK_WALL_Z_M;
    let operator =
        VirtualOperator::touch_and_slide(start, wall_z_m, 0.02, 0.08, 6.0).repeating(6.0);
    let sensors = SensorModel {
        seed: sensor_seed,
        converter: Some(crate::tension_budget::converter_model(config)),
        ..SensorModel::default()
    };
    let mut twin = Twin::new(params, start, operator, sensors);
    twin.set_torque_step_nm(Some(twin_torque_step_nm(config)));
    DemoScene {
        twin,
        wall: check_wall(),
        wall_z_m,
    }
}

/// Distance of the check wall from the frame's plane, metres.
pub const CHECK_WALL_Z_M: f64 = 0.33;

/// The check wall: a flat virtual wall parallel to the frame, [`CHECK_WALL_Z_M`] in front of
/// it, solid beyond, its outward normal towards the wearer (`-z`).
pub fn check_wall() -> Plane {
    Plane::new(
        videt_control::Vec3::new(0.0, 0.0, CHECK_WALL_Z_M),
        videt_control::Vec3::new(0.0, 0.0, -1.0),
    )
    .expect("constant wall is valid")
}
