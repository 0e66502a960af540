//! The twin's demonstration scenes: the twin of the configured device in front of the check
//! wall, with a virtual operator who touches it and slides along it.

use videt_config::Config;
use videt_control::{Plane, Rig3, WireDevice};
use videt_runtime::runtime_device::RuntimeDevice;
use videt_runtime::setup::{check_wall, rig, transmission, twin_torque_step_nm, CHECK_WALL_Z_M};
use videt_sim::{PlantParams, SensorModel, VirtualOperator, WireModules};

/// The twin's demonstration scene: a wall in front of the frame, and a virtual operator who
/// touches it, slides along it and comes back, over and over.
#[derive(Debug)]
pub struct WallScene<const N: usize, D: WireDevice<N>> {
    /// The twin, with the thimble in front of the frame's centre.
    pub twin: videt_sim::Twin<N, D>,
    /// The wall (solid beyond `z = wall_z_m`, outward normal towards the user, `-z`).
    pub wall: Plane,
    /// Where the wall is, metres.
    pub wall_z_m: f64,
}

/// The WireMan's demonstration scene.
pub type WiremanWallScene = WallScene<3, Rig3>;

/// Build the demonstration scene for the configured rig (the twin's guides are the configured
/// ones: on the twin the configuration is the truth; its motors apply torque in the configured
/// drive's steps, [`twin_torque_step_nm`](videt_runtime::setup::twin_torque_step_nm)).
pub fn wireman_wall_scene(config: &Config, sensor_seed: u64) -> WiremanWallScene {
    // A configuration whose guides make no rig is refused on load; the paper's frame stands in.
    let device = rig(config).unwrap_or(PlantParams::paper_default().device);
    let g = device.guides_m();
    let start = (g[0] + g[1] + g[2]) / 3.0 + videt_sim::Vec3::new(0.0, 0.0, 0.30);
    wall_scene(config, device, start, sensor_seed)
}

/// Where the thimble starts in a device's demonstration scene: 0.3 m in front of its guides'
/// centre (the one-wire device's a little off its guide's axis, where the azimuth is defined).
pub fn thimble_start<const N: usize, D: RuntimeDevice<N>>(device: &D) -> videt_sim::Vec3 {
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
pub fn wall_scene<const N: usize, D: WireDevice<N>>(
    config: &Config,
    device: D,
    start: videt_sim::Vec3,
    sensor_seed: u64,
) -> WallScene<N, D> {
    let mut params = PlantParams::for_device(device);
    params.transmission = transmission(config);
    params.wire_ea_n = config.transmission.wire_ea_n;
    let wall_z_m = CHECK_WALL_Z_M;
    let operator =
        VirtualOperator::touch_and_slide(start, wall_z_m, 0.02, 0.08, 6.0).repeating(6.0);
    let sensors = SensorModel {
        seed: sensor_seed,
        converter: Some(videt_runtime::tension_budget::converter_model(config)),
        ..SensorModel::default()
    };
    let mut twin = videt_sim::Twin::new(params, start, operator, sensors);
    twin.set_torque_step_nm(Some(twin_torque_step_nm(config)));
    // The configured modules' inside wire stretches in series with the free wire.
    twin.plant_mut().set_modules(WireModules {
        inside_length_m: [config.transmission.inside_wire_m; N],
        ..WireModules::default()
    });
    WallScene {
        twin,
        wall: check_wall(),
        wall_z_m,
    }
}
