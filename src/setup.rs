//! Building the runtime's pieces from the configuration: rig, control step, cycle, and the
//! digital twin's demonstration scene.

use crate::runtime_device::RuntimeDevice;
use videt_control::safety::SafetyLimits;
use videt_control::{
    Algorithm, ControlParams, ControlStep, ForceField, ForceLimits, PlanarDevice, Plane,
    PolarDevice, Rig3, Rig4, RigError, RigPlanar, TensionPiGains, WireDevice,
};
use videt_hal::Transmission;
use videt_rt_config::Config;
use videt_sim::{PlantParams, SensorModel, VirtualOperator};

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

/// The twin's demonstration scene: a wall in front of the frame, and a virtual operator who
/// touches it, slides along it and comes back, over and over.
#[derive(Debug)]
pub struct DemoSceneOf<const N: usize, D: WireDevice<N>> {
    /// The twin, with the thimble in front of the frame's centre.
    pub twin: videt_sim::Twin<N, D>,
    /// The wall (solid beyond `z = wall_z_m`, outward normal towards the user, `-z`).
    pub wall: Plane,
    /// Where the wall is, metres.
    pub wall_z_m: f64,
}

/// The WireMan's demonstration scene.
pub type DemoScene = DemoSceneOf<3, Rig3>;

/// Build the demonstration scene for the configured rig (the twin's guides are the configured
/// ones: on the twin the configuration is the truth; its motors apply torque in the configured
/// drive's steps, [`twin_torque_step_nm`]).
pub fn demo_scene(config: &Config, sensor_seed: u64) -> DemoScene {
    // A configuration whose guides make no rig is refused on load; the paper's frame stands in.
    let device = rig(config).unwrap_or(PlantParams::paper_default().device);
    let g = device.guides_m();
    let start = (g[0] + g[1] + g[2]) / 3.0 + videt_sim::Vec3::new(0.0, 0.0, 0.30);
    demo_scene_for(config, device, start, sensor_seed)
}

/// Where the thimble starts in a device's demonstration scene: 0.3 m in front of its guides'
/// centre (the one-wire device's a little off its guide's axis, where the azimuth is defined).
pub fn demo_start<const N: usize, D: RuntimeDevice<N>>(device: &D) -> videt_sim::Vec3 {
    let g = device.logged_guides_m();
    let centre = g[..N].iter().fold(videt_sim::Vec3::zeros(), |c, p| {
        c + videt_sim::Vec3::new(p[0], p[1], p[2])
    }) / N as f64;
    let off_axis = if N == 1 {
        videt_sim::Vec3::new(0.06, 0.04, 0.0)
    } else {
        videt_sim::Vec3::zeros()
    };
    device.constrain(&(centre + off_axis + videt_sim::Vec3::new(0.0, 0.0, 0.30)))
}

/// The check wall's demonstration on any device: the twin of `device` with the configured
/// transmission, sensors and torque steps, the thimble at `start`, a virtual operator who
/// touches the wall, slides along it and comes back, over and over.
pub fn demo_scene_for<const N: usize, D: WireDevice<N>>(
    config: &Config,
    device: D,
    start: videt_sim::Vec3,
    sensor_seed: u64,
) -> DemoSceneOf<N, D> {
    let mut params = PlantParams::for_device(device);
    params.transmission = transmission(config);
    let wall_z_m = CHECK_WALL_Z_M;
    let operator =
        VirtualOperator::touch_and_slide(start, wall_z_m, 0.02, 0.08, 6.0).repeating(6.0);
    let sensors = SensorModel {
        seed: sensor_seed,
        converter: Some(crate::tension_budget::converter_model(config)),
        ..SensorModel::default()
    };
    let mut twin = videt_sim::Twin::new(params, start, operator, sensors);
    twin.set_torque_step_nm(Some(twin_torque_step_nm(config)));
    DemoSceneOf {
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
