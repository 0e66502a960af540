//! How the twin's HAL channels reach its wires: the rig as built (a motor, an encoder or a load
//! cell wired the other way, drives or sensors on the wrong wires, the e-stop's level), seen
//! through what the configuration corrects. The identity is a rig wired as configured.

/// The wiring of an `N`-wire twin, channel by channel (a channel is a wire as the HAL numbers
/// it: the configuration's wire order).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Wiring<const N: usize> {
    /// The wire each drive channel turns and reads the encoder of.
    pub drive_wire: [usize; N],
    /// Per drive channel: its torque turns its wire the other way (a positive torque unwinds).
    pub motor_reversed: [bool; N],
    /// Per drive channel: its encoder counts the other way (down as the wire winds in).
    pub encoder_reversed: [bool; N],
    /// The wire each tension channel reads.
    pub sensor_wire: [usize; N],
    /// Per tension channel: the reading has the other sign.
    pub cell_inverted: [bool; N],
    /// The e-stop reads pressed while released, and released while pressed.
    pub estop_inverted: bool,
}

impl<const N: usize> Default for Wiring<N> {
    fn default() -> Self {
        Wiring {
            drive_wire: core::array::from_fn(|i| i),
            motor_reversed: [false; N],
            encoder_reversed: [false; N],
            sensor_wire: core::array::from_fn(|i| i),
            cell_inverted: [false; N],
            estop_inverted: false,
        }
    }
}

impl<const N: usize> Wiring<N> {
    /// Whether each of `drive_wire` and `sensor_wire` names every wire once.
    pub fn is_valid(&self) -> bool {
        let permutation = |p: &[usize; N]| {
            let mut seen = [false; N];
            p.iter()
                .all(|&w| w < N && !core::mem::replace(&mut seen[w], true))
        };
        permutation(&self.drive_wire) && permutation(&self.sensor_wire)
    }

    /// The sign a drive channel's torque reaches its wire with.
    pub fn motor_sign(&self, channel: usize) -> f64 {
        if self.motor_reversed[channel] {
            -1.0
        } else {
            1.0
        }
    }

    /// The sign a drive channel's encoder counts its wire's winding with.
    pub fn encoder_sign(&self, channel: usize) -> f64 {
        if self.encoder_reversed[channel] {
            -1.0
        } else {
            1.0
        }
    }

    /// The sign a tension channel reads its wire's tension with.
    pub fn cell_sign(&self, channel: usize) -> f64 {
        if self.cell_inverted[channel] {
            -1.0
        } else {
            1.0
        }
    }

    /// The torque on each wire from the drive channels' `channel_torque_nm`.
    pub fn wire_torques(&self, channel_torque_nm: &[f64; N]) -> [f64; N] {
        let mut t = [0.0; N];
        for (k, torque) in channel_torque_nm.iter().enumerate() {
            t[self.drive_wire[k]] += self.motor_sign(k) * torque;
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_identity_wires_every_channel_to_its_own_wire_the_right_way() {
        let w = Wiring::<3>::default();
        assert!(w.is_valid());
        assert_eq!(w.wire_torques(&[0.1, -0.2, 0.3]), [0.1, -0.2, 0.3]);
        assert_eq!((w.encoder_sign(1), w.cell_sign(2)), (1.0, 1.0));
    }

    #[test]
    fn swapped_drives_and_a_reversed_motor_move_the_wires_they_reach() {
        let w = Wiring::<3> {
            drive_wire: [2, 1, 0],
            motor_reversed: [false, false, true],
            ..Wiring::default()
        };
        assert!(w.is_valid());
        assert_eq!(w.wire_torques(&[0.1, 0.2, 0.3]), [-0.3, 0.2, 0.1]);
        let twice = Wiring::<3> {
            drive_wire: [0, 0, 2],
            ..Wiring::default()
        };
        assert!(!twice.is_valid());
    }
}
