//! Building the runtime's pieces from the configuration: rig, transmission, control step,
//! cycle, and the check wall.

use videt_config::{Config, ReliefShapeName};
use videt_control::safety::SafetyLimits;
use videt_control::{
    Algorithm, ControlParams, ControlStep, ForceField, ForceLimits, PlanarDevice, Plane,
    PolarDevice, Rig3, Rig4, RigError, RigPlanar, TensionPiGains, WireDevice, WireStretch,
};
use videt_relief::{ReliefLayout, ReliefShape};

use crate::cycle::{ControlCycle, CycleSettings, WireZero};

pub use crate::drive_train::{transmission, twin_rated_torque_mnm, twin_torque_step_nm, whole_mnm};

/// The rig geometry of the configuration.
pub fn rig(config: &Config) -> Result<Rig3, RigError> {
    let g = &config.rig.guides_m;
    Rig3::new(core::array::from_fn(|i| {
        videt_control::Vec3::new(g[i][0], g[i][1], 0.0)
    }))
}

/// The planar two-wire device of the configuration (`rig.planar_guides_x_m`).
pub fn planar_device(config: &Config) -> Result<PlanarDevice, RigError> {
    RigPlanar::new(config.rig.planar_guides_x_m).map(PlanarDevice::new)
}

/// The one-wire device of the configuration (`rig.polar_guide_m`).
pub fn polar_device(config: &Config) -> Result<PolarDevice, String> {
    let [x, y, z] = config.rig.polar_guide_m;
    PolarDevice::new(videt_control::Vec3::new(x, y, z)).map_err(|e| e.to_string())
}

/// The four-wire device of the configuration (`rig.spidar_guides_m`).
pub fn spidar_device(config: &Config) -> Result<Rig4, RigError> {
    Rig4::new(
        config
            .rig
            .spidar_guides_m
            .map(|g| videt_control::Vec3::new(g[0], g[1], g[2])),
    )
}

/// The control step for a rig.
pub fn control_step(config: &Config, rig: Rig3) -> crate::WiremanStep {
    control_step_for(config, rig)
}

/// The control step for any device, with the configured gains and limits.
pub fn control_step_for<const N: usize, D: WireDevice<N>>(
    config: &Config,
    device: D,
) -> ControlStep<N, D> {
    let c = &config.control;
    let tr = transmission(config);
    let feedforward = tr.torque_for_tension(1.0);
    // The configuration was validated: the name is known.
    let algorithm = Algorithm::from_name(&c.algorithm).unwrap_or_default();
    // A sensor too slow for the configured gains runs them reduced when the configuration
    // allows it (a configuration that does not is refused before this).
    let gain_scale = crate::tension_budget::plan(config).map_or(1.0, |p| p.gain_scale());
    ControlStep::new(
        device,
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
                integral_speed_gate_m_s: if c.tension_integral_speed_gate_m_s > 0.0 {
                    c.tension_integral_speed_gate_m_s
                } else {
                    f64::INFINITY
                },
            },
            field: ForceField::towards_frame(c.field_n),
            free_space_field_n: c.free_space_field_n,
            stretch: if c.stretch_compensation {
                WireStretch {
                    axial_stiffness_n: config.transmission.wire_ea_n,
                    inside_length_m: config.transmission.inside_wire_m,
                }
            } else {
                WireStretch::RIGID
            },
        },
    )
}

/// The control cycle for a rig, with the encoder zero and whether the rig is calibrated.
pub fn control_cycle(
    config: &Config,
    rig: Rig3,
    wire_zero: WireZero,
    calibrated: bool,
) -> crate::WiremanCycle {
    control_cycle_for(config, rig, wire_zero, calibrated)
}

/// The control cycle for any device, with the encoder zero and whether it is calibrated.
pub fn control_cycle_for<const N: usize, D: WireDevice<N>>(
    config: &Config,
    device: D,
    wire_zero: WireZero,
    calibrated: bool,
) -> ControlCycle<N, D> {
    let c = &config.control;
    ControlCycle::new(
        control_step_for(config, device),
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

/// Where the relief sits: a 20 x 15 cm area centred in front of the configured guides, back
/// plane at 36 cm, 4 cm of relief, the configured shape (`vision.relief_shape`).
pub fn relief_layout(config: &Config) -> ReliefLayout {
    let shape = match config.vision.relief_shape {
        ReliefShapeName::Interpolated => ReliefShape::Interpolated,
        ReliefShapeName::Stepped => ReliefShape::Stepped,
    };
    ReliefLayout::in_front_of(&config.rig.guides_m, shape)
}
