//! The check's steps on the rig, in the order they run: the e-stop released, each sensor's
//! zero, each drive's winding test (its wire, its direction, its sensor's sign and scale), each
//! encoder against a wire pulled out to a mark, the drives on the wrong wires, the e-stop
//! pressed.

use videt_config::edit::{Fix, FixValue};
use videt_config::TensionAdc;
use videt_control::autoinit::Failure;
use videt_runtime::WIREMAN_WIRES;

use super::bench::{Bench, Stretch, Winding};
use super::{CommissionStep, CommissionTechnician, StepReport};
use crate::init::runner::InitHardware;

/// Each drive's winding test, `None` for a drive no sensor answered.
pub(super) type Windings = [Option<Winding>; WIREMAN_WIRES];

impl<H: InitHardware, T: CommissionTechnician<H>> Bench<'_, H, T> {
    /// The e-stop released, before any motor moves: whether it reads so. When it does not,
    /// the technician presses it to tell a level the other way from a line that never changes.
    pub fn estop_released(&mut self) -> Result<bool, Failure> {
        self.manual_step(CommissionStep::ReleaseEStop)?;
        if !self.estop_reads_pressed()? {
            self.steps.push(StepReport::pass(
                "estop.released",
                "the e-stop input reads released",
            ));
            return Ok(true);
        }
        self.manual_step(CommissionStep::PressEStop)?;
        let pressed_reads_released = !self.estop_reads_pressed()?;
        let s = &self.config.sensors;
        let step = if pressed_reads_released {
            let other = s.estop_pressed_level.other().name();
            StepReport::fail(
                "estop.released",
                "the e-stop input reads pressed while the button is released, and released while it is pressed: its level is the other one",
                vec![Fix::new("sensors.estop_pressed_level", None, FixValue::Text(other.into()))],
            )
        } else {
            StepReport::fail(
                "estop.released",
                "the e-stop input reads pressed whether the button is released or pressed",
                Vec::new(),
            )
            .with_wiring(format!(
                "check the e-stop's wiring to line {} of {} (sensors.estop_line, sensors.gpio_chip): a cut wire or another line",
                s.estop_line, s.gpio_chip
            ))
        };
        self.steps.push(step);
        self.manual_step(CommissionStep::ReleaseEStop)?;
        for name in ["drives", "sensors", "estop.pressed"] {
            self.steps.push(StepReport::skipped(
                name,
                "not checked: the motors are not driven without a working e-stop (fix it and run the check again)",
            ));
        }
        Ok(false)
    }

    /// Each sensor's reading at rest, every motor idle: within 1 N of zero. The readings.
    pub fn zeros(&mut self) -> Result<Stretch, Failure> {
        let rest = self.idle(0.5)?;
        let s = &self.config.sensors;
        for (j, offset) in rest.mean_tension_n.iter().enumerate() {
            let name = format!("sensor{j}.zero");
            let counts = offset / s.newtons_per_count[j];
            self.steps.push(if offset.abs() <= 1.0 {
                StepReport::pass(
                    name,
                    format!("reads {offset:+.2} N at rest ({counts:+.0} counts from sensors.zero_counts[{j}])"),
                )
            } else {
                let zero = f64::from(s.zero_counts[j]) + counts;
                StepReport::fail(
                    name,
                    format!("reads {offset:+.2} N at rest, more than 1 N"),
                    vec![Fix::new(
                        "sensors.zero_counts",
                        Some(j),
                        FixValue::Integer(zero.round() as i64),
                    )],
                )
            });
        }
        Ok(rest)
    }

    /// Each drive's winding test against the readings at `rest`, and the wire each moves: the
    /// windings, and which drive was found on each wire when every wire has its own.
    pub fn wires(
        &mut self,
        rest: &Stretch,
    ) -> Result<(Windings, Option<[usize; WIREMAN_WIRES]>), Failure> {
        let mut windings: Windings = [None; WIREMAN_WIRES];
        for (k, w) in windings.iter_mut().enumerate() {
            *w = self.winding_test(k, rest)?;
        }
        let node_ids = self.config.drives.node_ids;
        let follows_drives = self.config.sensors.adc == TensionAdc::Drive;
        let mut drive_of_wire: [Option<usize>; WIREMAN_WIRES] = [None; WIREMAN_WIRES];
        for (k, w) in windings.iter().enumerate() {
            let name = format!("drive{k}.wire");
            let Some(w) = w else {
                self.steps.push(
                    StepReport::fail(
                        name,
                        format!(
                            "no tension sensor answered drive {k} (node {}) under either direction of its test torque",
                            node_ids[k]
                        ),
                        Vec::new(),
                    )
                    .with_wiring(format!(
                        "check that drive {k}'s motor turns a pulley whose wire ends in a sphere resting against its ring, and that the wire's load cell is connected"
                    )),
                );
                continue;
            };
            if drive_of_wire[w.sensor].replace(k).is_some() {
                self.steps.push(
                    StepReport::fail(
                        name,
                        format!(
                            "drive {k} moves the wire at ring {} that another drive moves too",
                            w.sensor
                        ),
                        Vec::new(),
                    )
                    .with_wiring("each motor must turn its own wire's pulley"),
                );
                continue;
            }
            let moved = format!(
                "drive {k} (node {}) moves the wire at ring {}: sensor {} answered {:+.2} N",
                node_ids[k], w.sensor, w.sensor, w.change_n
            );
            self.steps.push(if follows_drives {
                StepReport::pass(
                    name,
                    format!("{moved} (with sensors.adc = \"drive\" a sensor follows its drive: which wire a drive moves is not told by the sensors)"),
                )
            } else if w.sensor == k {
                StepReport::pass(name, moved)
            } else {
                StepReport::fail(
                    name,
                    format!("{moved}, not the wire at ring {k} (drives.wires has the fix)"),
                    Vec::new(),
                )
            });
        }
        let found = drive_of_wire
            .iter()
            .copied()
            .collect::<Option<Vec<usize>>>()
            .and_then(|v| v.try_into().ok())
            .filter(|_| !follows_drives);
        Ok((windings, found))
    }

    /// Each drive's direction and its sensor's sign and scale, from `windings`: the motors'
    /// reversals as they should be.
    pub fn directions(&mut self, windings: &Windings) -> [bool; WIREMAN_WIRES] {
        let test_n = self.config.commission.test_tension_n;
        let s = &self.config.sensors;
        let mut reversed = self.config.drives.motor_reversed;
        for (k, w) in windings.iter().enumerate() {
            let name = format!("drive{k}.direction");
            let Some(w) = w else {
                self.steps.push(StepReport::skipped(
                    name,
                    "not checked: the drive's wire was not found",
                ));
                continue;
            };
            self.steps.push(if w.sign > 0.0 {
                StepReport::pass(
                    name,
                    format!("a positive torque winds the wire at ring {}", w.sensor),
                )
            } else {
                reversed[k] = !reversed[k];
                StepReport::fail(
                    name,
                    format!(
                        "a positive torque unwinds the wire at ring {} (the opposite torque winds it)",
                        w.sensor
                    ),
                    vec![Fix::new(
                        "drives.motor_reversed",
                        Some(k),
                        FixValue::Bool(reversed[k]),
                    )],
                )
            });
            let j = w.sensor;
            let scale = w.change_n.abs() / test_n;
            let reads = format!(
                "reads {:+.2} N while its wire is pulled at {test_n:.2} N (x{scale:.2})",
                w.change_n
            );
            let (problem, factor) = match (w.change_n < 0.0, (0.5..=2.0).contains(&scale)) {
                (false, true) => (None, 1.0),
                (true, true) => (Some("the load cell is read the other way"), -1.0),
                (false, false) => (Some("its scale is far off"), 1.0 / scale),
                (true, false) => (
                    Some("the load cell is read the other way and its scale is far off"),
                    -1.0 / scale,
                ),
            };
            let name = format!("sensor{j}.sign-and-scale");
            self.steps.push(match problem {
                None => StepReport::pass(
                    name,
                    format!("{reads}; `videt tension-calibrate` measures it exactly"),
                ),
                Some(problem) => StepReport::fail(
                    name,
                    format!("{reads}: {problem}"),
                    vec![Fix::new(
                        "sensors.newtons_per_count",
                        Some(j),
                        FixValue::Float(factor * s.newtons_per_count[j]),
                    )],
                ),
            });
        }
        reversed
    }

    /// Each encoder against its wire pulled out to the mark by the technician, motor idle:
    /// the encoders' reversals as they should be.
    pub fn encoders(&mut self, windings: &Windings) -> Result<[bool; WIREMAN_WIRES], Failure> {
        let mut reversed = self.config.drives.encoder_reversed;
        let metres_per_count = self.runner.settings().transmission.metres_per_count();
        let pull_m = self.config.commission.pull_out_m;
        for (k, w) in windings.iter().enumerate() {
            let name = format!("drive{k}.encoder");
            let Some(w) = w else {
                self.steps.push(StepReport::skipped(
                    name,
                    "not checked: the drive's wire was not found",
                ));
                continue;
            };
            let ring = w.sensor;
            let before = self.held_counts(k, w)?;
            self.manual_step(CommissionStep::PullOutWire {
                ring,
                length_m: pull_m,
            })?;
            let after = self.idle(0.2)?.counts.1[k];
            self.tech
                .perform_commission(CommissionStep::LetGo { ring }, self.hw)?;
            self.wind_back(k, w)?;
            let counted = (after - before) as f64;
            let expected = -pull_m / metres_per_count;
            let ratio = counted / expected;
            let per_mm = |c: f64| c.abs() / (pull_m * 1e3);
            let measured = format!(
                "{counted:+.0} counts for the {:.0} mm pulled out ({:.1} counts/mm; the transmission configured gives {:.1})",
                pull_m * 1e3,
                per_mm(counted),
                per_mm(expected)
            );
            self.steps.push(if ratio.abs() < 0.1 {
                StepReport::fail(name, format!("{measured}: the encoder did not count"), Vec::new())
                    .with_wiring(format!("check drive {k}'s encoder cable and that its encoder is on the motor turning the wire at ring {ring}"))
            } else if ratio < 0.0 {
                reversed[k] = !reversed[k];
                StepReport::fail(
                    name,
                    format!("{measured}: it counts up as the wire pays out"),
                    vec![Fix::new(
                        "drives.encoder_reversed",
                        Some(k),
                        FixValue::Bool(reversed[k]),
                    )],
                )
            } else if (ratio - 1.0).abs() > 0.05 {
                StepReport::fail(
                    name,
                    format!("{measured}: {:.1} % off", (ratio - 1.0) * 100.0),
                    Vec::new(),
                )
                .with_wiring("check transmission.counts_per_motor_rev, transmission.gear_ratio and transmission.pulley_radius_m against the parts fitted")
            } else {
                StepReport::pass(name, measured)
            });
        }
        Ok(reversed)
    }

    /// Drives on the wrong wires (`found[j]` the drive found on wire j): one fix, the node ids
    /// in the order of the wires they move, each drive's reversals (as they should be) with it.
    pub fn wrong_wires(
        &mut self,
        found: [usize; WIREMAN_WIRES],
        motor_reversed: [bool; WIREMAN_WIRES],
        encoder_reversed: [bool; WIREMAN_WIRES],
    ) {
        if found.iter().enumerate().all(|(j, k)| j == *k) {
            return;
        }
        let d = &self.config.drives;
        let ids = found.map(|k| FixValue::Integer(i64::from(d.node_ids[k])));
        let mut fixes = vec![Fix::new(
            "drives.node_ids",
            None,
            FixValue::List(ids.to_vec()),
        )];
        for (key, now, fixed) in [
            ("drives.motor_reversed", d.motor_reversed, motor_reversed),
            (
                "drives.encoder_reversed",
                d.encoder_reversed,
                encoder_reversed,
            ),
        ] {
            let placed = found.map(|k| fixed[k]);
            if placed != now {
                fixes.push(Fix::new(
                    key,
                    None,
                    FixValue::List(placed.map(FixValue::Bool).to_vec()),
                ));
            }
        }
        let mut rings = [0; WIREMAN_WIRES];
        for (j, k) in found.iter().enumerate() {
            rings[*k] = j;
        }
        self.steps.push(StepReport::fail(
            "drives.wires",
            format!(
                "drives 0, 1, 2 move the wires at rings {}, {}, {}: the node ids go in the order of the wires they move (each drive's directions with it)",
                rings[0], rings[1], rings[2]
            ),
            fixes,
        ));
    }

    /// The e-stop pressed by the technician, every motor idle, then released.
    pub fn estop_pressed(&mut self) -> Result<(), Failure> {
        self.manual_step(CommissionStep::PressEStop)?;
        let pressed = self.estop_reads_pressed()?;
        self.manual_step(CommissionStep::ReleaseEStop)?;
        let _ = self.hw.reset();
        let s = &self.config.sensors;
        self.steps.push(if pressed {
            StepReport::pass("estop.pressed", "the e-stop input reads pressed")
        } else {
            StepReport::fail(
                "estop.pressed",
                "the e-stop input reads released while the button is pressed",
                Vec::new(),
            )
            .with_wiring(format!(
                "check that the e-stop is wired to line {} of {} (sensors.estop_line, sensors.gpio_chip)",
                s.estop_line, s.gpio_chip
            ))
        });
        Ok(())
    }
}
