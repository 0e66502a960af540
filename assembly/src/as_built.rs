//! The rig as built, on the twin: the wiring mistakes a newly assembled WireMan may have, and
//! the twin's [`Wiring`] they make once the configuration's corrections are applied, as the
//! drivers apply them on the device.
//!
//! The rig as built does not depend on the configuration: its drives carry the configured
//! node ids in ascending order on wires 0, 1, 2 (before any swap), so reordering
//! `drives.node_ids` in the configuration fixes a swap and a configuration's own mistake shows
//! as one.

use videt_config::{Config, LineLevel, TensionAdc};
use videt_runtime::WIREMAN_WIRES;
use videt_sim::Wiring;

/// One wiring mistake of the rig as built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WiringMistake {
    /// The motor on this wire turns the other way: a positive torque unwinds it.
    ReversedMotor(usize),
    /// The encoder on this wire counts the other way.
    ReversedEncoder(usize),
    /// The drives of these two wires carry each other's node ids.
    SwappedNodes(usize, usize),
    /// The load cell of this wire is wired inverted (its bridge's outputs swapped).
    InvertedCell(usize),
    /// The e-stop input is at its other level (a normally-open button where the configuration
    /// expects a normally-closed one).
    EStopLevel,
    /// The left and right cameras are swapped.
    SwappedCameras,
}

impl WiringMistake {
    /// Parse a mistake's name as `--sim-fault` gives it: `reversed-motor:N`,
    /// `reversed-encoder:N`, `swapped-nodes:A,B`, `inverted-cell:N`, `estop-level`,
    /// `swapped-cameras`. `None` when `text` names no wiring mistake.
    pub fn parse(text: &str) -> Option<Result<WiringMistake, String>> {
        let (name, arg) = text.split_once(':').unwrap_or((text, ""));
        let wire = |s: &str| {
            s.trim()
                .parse::<usize>()
                .ok()
                .filter(|w| *w < WIREMAN_WIRES)
                .ok_or_else(|| format!("--sim-fault {text:?}: wire {s:?} must be 0, 1 or 2"))
        };
        let none = |m: WiringMistake| {
            if arg.is_empty() {
                Ok(m)
            } else {
                Err(format!("--sim-fault {text:?}: {name} takes no wire"))
            }
        };
        Some(match name {
            "reversed-motor" => wire(arg).map(WiringMistake::ReversedMotor),
            "reversed-encoder" => wire(arg).map(WiringMistake::ReversedEncoder),
            "inverted-cell" => wire(arg).map(WiringMistake::InvertedCell),
            "swapped-nodes" => match arg.split_once(',') {
                Some((a, b)) => match (wire(a), wire(b)) {
                    (Ok(a), Ok(b)) if a != b => Ok(WiringMistake::SwappedNodes(a, b)),
                    (Err(e), _) | (_, Err(e)) => Err(e),
                    _ => Err(format!("--sim-fault {text:?}: two different wires")),
                },
                None => Err(format!("--sim-fault {text:?}: must be swapped-nodes:A,B")),
            },
            "estop-level" => none(WiringMistake::EStopLevel),
            "swapped-cameras" => none(WiringMistake::SwappedCameras),
            _ => return None,
        })
    }
}

/// The node ids a rig built with `mistakes` carries on wires 0, 1, 2: `ids` in ascending
/// order, then each swap.
pub fn built_node_ids(
    mut ids: [u8; WIREMAN_WIRES],
    mistakes: &[WiringMistake],
) -> [u8; WIREMAN_WIRES] {
    ids.sort_unstable();
    for m in mistakes {
        if let WiringMistake::SwappedNodes(a, b) = *m {
            ids.swap(a, b);
        }
    }
    ids
}

/// The twin's wiring for a rig built with `mistakes`, run with `config`.
pub fn twin_wiring(config: &Config, mistakes: &[WiringMistake]) -> Wiring<WIREMAN_WIRES> {
    // What the configuration corrects, on a rig built right.
    let configured = configured_wiring::<WIREMAN_WIRES>(config, DriveCorrections::InTwin);
    let built_ids = built_node_ids(config.drives.node_ids, mistakes);
    let mut motor_reversed = [false; WIREMAN_WIRES];
    let mut encoder_reversed = [false; WIREMAN_WIRES];
    let mut cell_inverted = [false; WIREMAN_WIRES];
    let mut estop_inverted = configured.estop_inverted;
    for m in mistakes {
        match *m {
            WiringMistake::ReversedMotor(w) => motor_reversed[w] ^= true,
            WiringMistake::ReversedEncoder(w) => encoder_reversed[w] ^= true,
            WiringMistake::InvertedCell(w) => cell_inverted[w] ^= true,
            WiringMistake::EStopLevel => estop_inverted ^= true,
            // The drives' order is in the built ids; the cameras are not wired to the HAL.
            WiringMistake::SwappedNodes(..) | WiringMistake::SwappedCameras => {}
        }
    }
    // Channel k talks to the drive with the configured id k, wherever it was built in.
    let drive_wire: [usize; WIREMAN_WIRES] = core::array::from_fn(|k| {
        built_ids
            .iter()
            .position(|id| *id == config.drives.node_ids[k])
            .unwrap_or(k)
    });
    // The converters are on their wires; through the drives, a cell follows its drive.
    let sensor_wire = if config.sensors.adc == TensionAdc::Drive {
        drive_wire
    } else {
        core::array::from_fn(|k| k)
    };
    Wiring {
        drive_wire,
        motor_reversed: core::array::from_fn(|k| {
            motor_reversed[drive_wire[k]] != configured.motor_reversed[k]
        }),
        encoder_reversed: core::array::from_fn(|k| {
            encoder_reversed[drive_wire[k]] != configured.encoder_reversed[k]
        }),
        sensor_wire,
        cell_inverted: core::array::from_fn(|k| {
            cell_inverted[sensor_wire[k]] != configured.cell_inverted[k]
        }),
        estop_inverted,
    }
}

/// Who applies the configuration's drive corrections (`drives.motor_reversed`,
/// `drives.encoder_reversed`) on a twin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriveCorrections {
    /// The HAL twin stands for the drives: its wiring applies them.
    InTwin,
    /// Drivers talk to simulated drives (the CAN twin): they apply them, as on the device.
    InDrivers,
}

/// The wiring of the twin of an `N`-wire rig built right, run with `config`: what the
/// configuration corrects and the rig does not need shows as the mistake it would make on the
/// device (a motor the configuration reverses unwinds under a winding torque, an e-stop read at
/// the other level reads pressed). The tension sensors' signs (`sensors.newtons_per_count`) and
/// the e-stop's level always; the drives' directions unless drivers apply them.
pub fn configured_wiring<const N: usize>(
    config: &Config,
    corrections: DriveCorrections,
) -> Wiring<N> {
    let in_twin = corrections == DriveCorrections::InTwin;
    let d = &config.drives;
    let key = |keys: &[bool; WIREMAN_WIRES], k: usize| in_twin && keys.get(k) == Some(&true);
    Wiring {
        motor_reversed: core::array::from_fn(|k| key(&d.motor_reversed, k)),
        encoder_reversed: core::array::from_fn(|k| key(&d.encoder_reversed, k)),
        cell_inverted: core::array::from_fn(|k| {
            config
                .sensors
                .newtons_per_count
                .get(k)
                .is_some_and(|n| *n < 0.0)
        }),
        estop_inverted: config.sensors.estop_pressed_level == LineLevel::High,
        ..Wiring::default()
    }
}

/// Whether the twin's cameras come swapped for a rig built with `mistakes`, run with
/// `config`: as built, the left camera is the first of `vision.devices` in sorted order.
pub fn cameras_swapped(config: &Config, mistakes: &[WiringMistake]) -> bool {
    let [left, right] = &config.vision.devices;
    let built_swapped = mistakes.contains(&WiringMistake::SwappedCameras);
    (left > right) != built_swapped
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_mistake_parses_and_other_names_are_not_wiring() {
        let parse = |t: &str| WiringMistake::parse(t).unwrap();
        assert_eq!(
            parse("reversed-motor:1"),
            Ok(WiringMistake::ReversedMotor(1))
        );
        assert_eq!(
            parse("reversed-encoder:2"),
            Ok(WiringMistake::ReversedEncoder(2))
        );
        assert_eq!(
            parse("swapped-nodes:0,2"),
            Ok(WiringMistake::SwappedNodes(0, 2))
        );
        assert_eq!(parse("inverted-cell:0"), Ok(WiringMistake::InvertedCell(0)));
        assert_eq!(parse("estop-level"), Ok(WiringMistake::EStopLevel));
        assert_eq!(parse("swapped-cameras"), Ok(WiringMistake::SwappedCameras));
        for bad in [
            "reversed-motor:3",
            "swapped-nodes:1,1",
            "swapped-nodes:1",
            "estop-level:1",
        ] {
            assert!(parse(bad).is_err(), "{bad}");
        }
        assert!(WiringMistake::parse("break:1:2").is_none());
    }

    #[test]
    fn a_rig_built_as_configured_is_wired_straight() {
        let mut config = Config::default();
        assert_eq!(twin_wiring(&config, &[]), Wiring::default());
        // Whatever order the ids are configured in, the rig was built with them.
        config.drives.node_ids = [7, 3, 5];
        let w = twin_wiring(&config, &[]);
        assert_eq!(w.drive_wire, [2, 0, 1]);
        // Nodes swapped as built: channel 1 moves wire 2 and channel 2 wire 1, until the
        // configuration swaps the ids too.
        config.drives.node_ids = [3, 5, 7];
        let swapped = [WiringMistake::SwappedNodes(1, 2)];
        assert_eq!(twin_wiring(&config, &swapped).drive_wire, [0, 2, 1]);
        config.drives.node_ids = [3, 7, 5];
        assert_eq!(twin_wiring(&config, &swapped), Wiring::default());
    }

    #[test]
    fn the_configuration_corrects_each_mistake_and_makes_its_own_when_wrong() {
        let mistakes = [
            WiringMistake::ReversedMotor(1),
            WiringMistake::ReversedEncoder(2),
            WiringMistake::InvertedCell(0),
            WiringMistake::EStopLevel,
        ];
        let mut config = Config::default();
        let w = twin_wiring(&config, &mistakes);
        assert_eq!(w.motor_reversed, [false, true, false]);
        assert_eq!(w.encoder_reversed, [false, false, true]);
        assert_eq!(w.cell_inverted, [true, false, false]);
        assert!(w.estop_inverted);
        config.drives.motor_reversed[1] = true;
        config.drives.encoder_reversed[2] = true;
        config.sensors.newtons_per_count[0] *= -1.0;
        config.sensors.estop_pressed_level = LineLevel::High;
        assert_eq!(twin_wiring(&config, &mistakes), Wiring::default());
        assert!(cameras_swapped(&config, &[WiringMistake::SwappedCameras]));
        config.vision.devices.swap(0, 1);
        assert!(!cameras_swapped(&config, &[WiringMistake::SwappedCameras]));
        assert!(cameras_swapped(&config, &[]));
        config.vision.devices.swap(0, 1);
        // The same corrections on a rig built right are mistakes of their own.
        let w = twin_wiring(&config, &[]);
        assert_eq!(w.motor_reversed, [false, true, false]);
        assert!(w.estop_inverted);
    }

    #[test]
    fn a_twin_built_right_shows_what_its_configuration_corrects_for_nothing() {
        let mut config = Config::default();
        assert_eq!(
            configured_wiring::<3>(&config, DriveCorrections::InTwin),
            Wiring::default()
        );
        config.drives.motor_reversed = [false, true, false];
        config.drives.encoder_reversed = [true, false, false];
        config.sensors.newtons_per_count[2] *= -1.0;
        config.sensors.estop_pressed_level = LineLevel::High;
        // As a rig built right and checked with this configuration (no mistakes) would be.
        let hal = configured_wiring::<3>(&config, DriveCorrections::InTwin);
        assert_eq!(hal, twin_wiring(&config, &[]));
        assert_eq!(hal.motor_reversed, [false, true, false]);
        // Behind drivers, the drives' keys are theirs; the cells and the e-stop stay the twin's.
        let can = configured_wiring::<3>(&config, DriveCorrections::InDrivers);
        assert_eq!(can.motor_reversed, [false; 3]);
        assert_eq!(can.encoder_reversed, [false; 3]);
        assert_eq!(can.cell_inverted, [false, false, true]);
        assert!(can.estop_inverted);
        // Fewer wires take the first keys.
        let planar = configured_wiring::<2>(&config, DriveCorrections::InTwin);
        assert_eq!(planar.motor_reversed, [false, true]);
        assert_eq!(planar.encoder_reversed, [true, false]);
    }
}
