//! What the control step needs of a wire device: the [`WireDevice`] trait (kinematics and force
//! distribution), the sensed values it takes, the settings and the tensions it returns, and the
//! kinds of device the runtime can drive. The devices implement it beside their kinematics (the
//! paper's three with the device module, the four-wire rig with its own).

use crate::algorithm::Algorithm;
use crate::distribution::ForceLimits;
use crate::field::ForceField;
use crate::kinematics::ForwardSolution;
use crate::Vec3;

/// The kinds of device the runtime can drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum DeviceKind {
    /// The wearable three-wire WireMan.
    Wireman3,
    /// The planar two-wire prototype of the paper's experiments (x-z plane).
    Planar2,
    /// One actuated wire whose direction two passive angle sensors measure (eq. 7).
    Polar1,
    /// Four wires from the corners of a frame around the workspace (every force direction).
    Spidar4,
}

impl DeviceKind {
    /// Every kind, in configuration order.
    pub const ALL: [DeviceKind; 4] = [
        DeviceKind::Wireman3,
        DeviceKind::Planar2,
        DeviceKind::Polar1,
        DeviceKind::Spidar4,
    ];

    /// The name used in configuration files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            DeviceKind::Wireman3 => "wireman3",
            DeviceKind::Planar2 => "planar2",
            DeviceKind::Polar1 => "polar1",
            DeviceKind::Spidar4 => "spidar4",
        }
    }

    /// The kind of a configuration name.
    pub fn from_name(name: &str) -> Option<DeviceKind> {
        DeviceKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Number of actuated wires.
    pub fn wires(self) -> usize {
        match self {
            DeviceKind::Wireman3 => 3,
            DeviceKind::Planar2 => 2,
            DeviceKind::Polar1 => 1,
            DeviceKind::Spidar4 => 4,
        }
    }

    /// The device measures the wire direction with two passive angle sensors.
    pub fn has_angle_sensors(self) -> bool {
        self == DeviceKind::Polar1
    }

    /// The thimble moves in the x-z plane only.
    pub fn is_planar(self) -> bool {
        self == DeviceKind::Planar2
    }
}

/// What the sensors tell the kinematics each period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensed<const N: usize> {
    /// Wire lengths, metres.
    pub lengths_m: [f64; N],
    /// Wire length rates, m/s (positive = paying out).
    pub length_rates_m_s: [f64; N],
    /// Passive angles (azimuth, elevation), radians; zero on devices without angle sensors.
    pub angles_rad: [f64; 2],
    /// Rates of the passive angles, rad/s.
    pub angle_rates_rad_s: [f64; 2],
}

impl<const N: usize> Default for Sensed<N> {
    fn default() -> Self {
        Sensed {
            lengths_m: [0.0; N],
            length_rates_m_s: [0.0; N],
            angles_rad: [0.0; 2],
            angle_rates_rad_s: [0.0; 2],
        }
    }
}

/// How the step asks a device for forces: the algorithm, its field and the tension limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceSettings {
    /// Control algorithm (field rule and projection).
    pub algorithm: Algorithm,
    /// Tension limits.
    pub limits: ForceLimits,
    /// The field `f_c` (magnitude 0 for P1/P2), in the paper's 3D frame.
    pub field: ForceField<3>,
    /// Free-space pull when the algorithm has no field, newtons (0 = wires held at `t_min`).
    pub free_space_field_n: f64,
}

/// Tension set-points and the force they make, in the paper's 3D frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WireTensions<const N: usize> {
    /// Tension set-points, newtons, each within `[t_min, t_max]`.
    pub tensions_n: [f64; N],
    /// The force those tensions make on the thimble, newtons.
    pub rendered_n: Vec3,
    /// Some tension had to be clamped at `t_max`.
    pub saturated: bool,
    /// The target was not reachable exactly.
    pub projected: bool,
}

impl<const N: usize> Default for WireTensions<N> {
    fn default() -> Self {
        WireTensions {
            tensions_n: [0.0; N],
            rendered_n: Vec3::zeros(),
            saturated: false,
            projected: false,
        }
    }
}

/// What a device makes of a desired force at one position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeviceForces<const N: usize> {
    /// The field force added (`f_c`, or the free-space pull), newtons.
    pub field_force_n: Vec3,
    /// What the projection aimed at, `f'_e = f_e + f_c` restricted to the directions the device
    /// spans, newtons.
    pub target_force_n: Vec3,
    /// The tensions and the force they make.
    pub tensions: WireTensions<N>,
}

/// A wire device: kinematics and force distribution. Every method is pure, allocation-free and
/// never returns NaN for finite input.
pub trait WireDevice<const N: usize>:
    Copy + core::fmt::Debug + PartialEq + Send + Sync + 'static
{
    /// The device's kind.
    const KIND: DeviceKind;

    /// Forward kinematics: the thimble position from the sensed lengths (and angles).
    fn forward(&self, sensed: &Sensed<N>) -> ForwardSolution;

    /// Thimble velocity at `position_m` from the sensed rates; `None` where singular.
    fn velocity(&self, position_m: &Vec3, sensed: &Sensed<N>) -> Option<Vec3>;

    /// Inverse kinematics: the wire lengths at a position.
    fn inverse(&self, position_m: &Vec3) -> [f64; N];

    /// The passive angles the sensors read at a position (zero without angle sensors).
    fn passive_angles(&self, _position_m: &Vec3) -> [f64; 2] {
        [0.0; 2]
    }

    /// The projection onto the directions the device's thimble moves in: the planar device's
    /// linkage holds it in the x-z plane (`y` dropped); other devices return the vector
    /// unchanged. Linear, so it applies to positions, velocities and forces alike (the twin
    /// uses it on all three).
    fn constrain(&self, position_m: &Vec3) -> Vec3 {
        *position_m
    }

    /// The unit direction along which wire `wire` pulls the thimble at `position_m`.
    fn pull_direction(&self, position_m: &Vec3, wire: usize) -> Vec3;

    /// The straight wire `wire` from its guide to `position_m`: its direction away from the
    /// guide and its length, metres (one square root: what a plant integrating at tens of kHz
    /// asks for each wire).
    fn wire_from_guide(&self, position_m: &Vec3, wire: usize) -> (Vec3, f64) {
        (
            -self.pull_direction(position_m, wire),
            self.inverse(position_m)[wire],
        )
    }

    /// The force of tensions `tensions_n` at `position_m`.
    fn force_of(&self, position_m: &Vec3, tensions_n: &[f64; N]) -> Vec3 {
        let mut f = Vec3::zeros();
        for (i, &t) in tensions_n.iter().enumerate() {
            f += self.pull_direction(position_m, i) * t;
        }
        f
    }

    /// Tensions for the contact force `desired_n` (already scaled by `scale`) plus the
    /// algorithm's field (scaled by `scale`), at `position_m`. `None` where the device cannot
    /// hold the thimble (a singular configuration): the caller holds every wire at `t_min`.
    fn forces(
        &self,
        position_m: &Vec3,
        desired_n: &Vec3,
        in_contact: bool,
        scale: f64,
        settings: &ForceSettings,
    ) -> Option<DeviceForces<N>>;
}

/// The unit vector along `d` (`+z` for a zero or non-finite vector) and its length.
pub(crate) fn unit_and_length(d: Vec3) -> (Vec3, f64) {
    let n = d.norm();
    if n > 1e-12 && n.is_finite() {
        (d / n, n)
    } else {
        (Vec3::z(), n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_names_round_trip() {
        for k in DeviceKind::ALL {
            assert_eq!(DeviceKind::from_name(k.name()), Some(k));
        }
        assert_eq!(DeviceKind::from_name("wireman"), None);
    }
}
