//! The digital twin a `--sim` run rehearses on, and its simulated technician.
//!
//! The twin starts at rest: every wire detached and fully wound, its end against its guide ring,
//! the encoders counting from arbitrary offsets (as incremental encoders do after power-up), the
//! strain gauges with their offset, gain error and noise. The technician connects the wires to
//! an empty thimble (no hand on it, only a light drag), fits new yarns and pulls them out.

use std::sync::atomic::AtomicBool;
use videt_assembly::as_built::{twin_wiring, WiringMistake};
use videt_assembly::WiremanTwin as Twin;
use videt_runtime::WIREMAN_WIRES;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use videt_config::Config;
use videt_control::autoinit::Failure;
use videt_sim::{PlantParams, SensorModel, TwinFault, Vec3, VirtualOperator, WireModules};

use super::runner::Runner;
use super::session::{Request, Technician};
use videt_runtime::setup;

/// The twin's set-up.
#[derive(Debug, Clone, PartialEq)]
pub struct TwinSetup {
    /// True guide points, metres (`z = 0`).
    pub guides_m: [Vec3; WIREMAN_WIRES],
    /// Seed of the encoder offsets, the sensor noise and where the technician puts the thimble.
    pub seed: u64,
    /// Sensor model (noise on by default).
    pub sensors: SensorModel<WIREMAN_WIRES>,
    /// Usable length of a newly fitted yarn, metres.
    pub new_wire_length_m: f64,
    /// Faults to rehearse.
    pub faults: Vec<SimFault>,
}

/// A fault to rehearse on the twin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SimFault {
    /// Wire `0` is left unconnected (its end stays at its ring).
    Disconnected(usize),
    /// A fault injected this many seconds after the wires were connected.
    After(f64, TwinFault),
    /// The rig was built with this wiring mistake.
    Wiring(WiringMistake),
}

/// Parse `--sim-fault`: `disconnected:N`, `estop:SECS`, `break:N:SECS`, `detach:N:SECS`,
/// `sensor:N:SECS`, `slip:N:MM:SECS` (SECS after the wires are connected), or a wiring
/// mistake of the rig as built: `reversed-motor:N`, `reversed-encoder:N`, `swapped-nodes:A,B`,
/// `inverted-cell:N`, `estop-level`, `swapped-cameras`. `transmission` converts a slip in
/// millimetres to encoder counts.
pub fn parse_fault(text: &str, transmission: &videt_hal::Transmission) -> Result<SimFault, String> {
    if let Some(mistake) = WiringMistake::parse(text) {
        return mistake.map(SimFault::Wiring);
    }
    let parts: Vec<&str> = text.split(':').collect();
    let wire = |s: &str| {
        s.parse::<usize>()
            .ok()
            .filter(|w| *w < WIREMAN_WIRES)
            .ok_or_else(|| format!("--sim-fault {text:?}: wire {s:?} must be 0, 1 or 2"))
    };
    let secs = |s: &str| {
        s.parse::<f64>()
            .ok()
            .filter(|t| t.is_finite() && *t >= 0.0 && *t <= 600.0)
            .ok_or_else(|| format!("--sim-fault {text:?}: time {s:?} must be seconds in [0, 600]"))
    };
    match parts.as_slice() {
        ["disconnected", n] => Ok(SimFault::Disconnected(wire(n)?)),
        ["estop", t] => Ok(SimFault::After(secs(t)?, TwinFault::PressEStop)),
        ["break", n, t] => Ok(SimFault::After(secs(t)?, TwinFault::BreakWire(wire(n)?))),
        ["detach", n, t] => Ok(SimFault::After(secs(t)?, TwinFault::DetachWire(wire(n)?))),
        ["sensor", n, t] => Ok(SimFault::After(
            secs(t)?,
            TwinFault::FailTensionSensor(wire(n)?),
        )),
        ["slip", n, mm, t] => {
            let mm = mm
                .parse::<f64>()
                .ok()
                .filter(|m| m.is_finite() && m.abs() <= 100.0)
                .ok_or_else(|| format!("--sim-fault {text:?}: slip {mm:?} must be millimetres in [-100, 100]"))?;
            let counts = (mm * 1e-3 / transmission.metres_per_count()).round() as i64;
            Ok(SimFault::After(secs(t)?, TwinFault::SlipWire(wire(n)?, counts)))
        }
        _ => Err(format!(
            "--sim-fault {text:?}: must be disconnected:N, estop:SECS, break:N:SECS, detach:N:SECS, sensor:N:SECS, slip:N:MM:SECS, \
             reversed-motor:N, reversed-encoder:N, swapped-nodes:A,B, inverted-cell:N, estop-level or swapped-cameras"
        )),
    }
}

impl TwinSetup {
    /// The wiring mistakes the rig was built with.
    pub fn wiring_mistakes(&self) -> Vec<WiringMistake> {
        self.faults
            .iter()
            .filter_map(|f| match f {
                SimFault::Wiring(m) => Some(*m),
                _ => None,
            })
            .collect()
    }

    /// A set-up on the configured guides with the default sensors and `seed`.
    pub fn from_config(config: &Config, seed: u64) -> TwinSetup {
        let g = &config.rig.guides_m;
        TwinSetup {
            guides_m: core::array::from_fn(|i| Vec3::new(g[i][0], g[i][1], 0.0)),
            seed,
            sensors: SensorModel {
                seed,
                converter: Some(videt_runtime::tension_budget::converter_model(config)),
                ..SensorModel::default()
            },
            new_wire_length_m: 1.5,
            faults: Vec::new(),
        }
    }
}

/// Parse `--sim-guides "X,Y;X,Y;X,Y"` (metres).
pub fn parse_guides(text: &str) -> Result<[Vec3; WIREMAN_WIRES], String> {
    let points: Vec<&str> = text.split(';').map(str::trim).collect();
    if points.len() != WIREMAN_WIRES {
        return Err(format!(
            "--sim-guides {text:?}: needs three points \"X,Y;X,Y;X,Y\" (metres), found {}",
            points.len()
        ));
    }
    let mut out = [Vec3::zeros(); WIREMAN_WIRES];
    for (i, p) in points.iter().enumerate() {
        let xy: Vec<&str> = p.split(',').map(str::trim).collect();
        let parse = |s: &str| {
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && v.abs() <= 2.0)
        };
        match (
            xy.len(),
            xy.first().and_then(|s| parse(s)),
            xy.get(1).and_then(|s| parse(s)),
        ) {
            (2, Some(x), Some(y)) => out[i] = Vec3::new(x, y, 0.0),
            _ => {
                return Err(format!(
                "--sim-guides point {i} = {p:?}: must be \"X,Y\" with finite numbers in [-2, 2] m"
            ))
            }
        }
    }
    Ok(out)
}

/// The twin at rest for `setup`, with the configured transmission.
pub fn rest_twin(config: &Config, setup: &TwinSetup) -> Twin {
    let mut params = PlantParams::paper_default();
    // The frame as built, even a degenerate one (the procedure must find that out).
    params.device = videt_control::Rig3::unchecked(setup.guides_m);
    params.transmission = setup::transmission(config);
    // An empty thimble: the terminal element and the three end spheres.
    params.thimble_mass_kg = 0.03;
    let centre = (setup.guides_m[0] + setup.guides_m[1] + setup.guides_m[2]) / 3.0;
    let mut twin = Twin::new(
        params,
        centre + Vec3::new(0.0, 0.0, 0.25),
        VirtualOperator::absent(0.2),
        setup.sensors.clone(),
    );
    twin.set_torque_step_nm(Some(setup::twin_torque_step_nm(config)));
    let plant = twin.plant_mut();
    plant.set_modules(WireModules::paper());
    plant.rest_detached();
    let mut rng = ChaCha8Rng::seed_from_u64(setup.seed);
    twin.set_encoder_offset_counts(core::array::from_fn(|_| {
        rng.random_range(-5_000_000_i64..5_000_000)
    }));
    // The rig as built (its wiring mistakes), with the configuration's corrections.
    let wiring = twin_wiring(config, &setup.wiring_mistakes());
    let valid = twin.set_wiring(wiring);
    debug_assert!(valid, "a wiring made from a permutation of the node ids");
    twin
}

/// The simulated technician: acts on the twin at once.
#[derive(Debug)]
pub struct SimTechnician {
    rng: ChaCha8Rng,
    new_wire_length_m: f64,
    faults: Vec<SimFault>,
    /// Messages received (the tool prints them).
    pub log: Vec<String>,
    /// Print messages to stderr as they come.
    pub echo: bool,
}

impl SimTechnician {
    /// The usable length of the yarns this technician fits from now on, metres.
    pub fn set_new_wire_length_m(&mut self, length_m: f64) {
        self.new_wire_length_m = length_m;
    }

    /// A technician for `setup`.
    pub fn new(setup: &TwinSetup) -> SimTechnician {
        SimTechnician {
            rng: ChaCha8Rng::seed_from_u64(setup.seed ^ 0x5eed),
            new_wire_length_m: setup.new_wire_length_m,
            faults: setup.faults.clone(),
            log: Vec::new(),
            echo: false,
        }
    }
}

impl SimTechnician {
    /// Do `request` on the twin at once (no time passes).
    pub fn act(&mut self, request: Request, hw: &mut Twin) -> Result<(), Failure> {
        match request {
            Request::ConnectWires => {
                // Somewhere in front of the frame, within the triangle's shadow.
                let g = *hw.plant().params().device.guides_m();
                let w: [f64; WIREMAN_WIRES] =
                    core::array::from_fn(|_| self.rng.random_range(0.2..1.0));
                let sum: f64 = w.iter().sum();
                let mut p = (g[0] * w[0] + g[1] * w[1] + g[2] * w[2]) / sum;
                p.z = self.rng.random_range(0.15..0.35);
                hw.plant_mut().connect_wires_at(p);
                let now = hw.sim_time();
                for fault in self.faults.drain(..) {
                    match fault {
                        SimFault::Disconnected(w) => {
                            hw.plant_mut().detach_wire(w);
                            hw.plant_mut().set_free_length_m(w, 0.0);
                        }
                        SimFault::After(secs, f) => {
                            let at = now.plus(std::time::Duration::from_secs_f64(secs));
                            if !hw.schedule_fault(at, f) {
                                return Err(Failure::Cancelled);
                            }
                        }
                        // Built in from the start.
                        SimFault::Wiring(_) => {}
                    }
                }
            }
            Request::FitNewWire { wire } => {
                let hanging = self.rng.random_range(0.1..0.4);
                hw.plant_mut()
                    .fit_new_wire(wire, hanging, self.new_wire_length_m);
            }
            Request::PullOutWire { wire } => {
                let usable = hw.plant().modules().usable_length_m[wire];
                hw.plant_mut().set_free_length_m(wire, usable);
            }
        }
        Ok(())
    }
}

/// A moment with the wires held, as after a person's action (50 periods).
pub fn hold_after_action<H: super::runner::InitHardware>(
    hw: &mut H,
    runner: &mut Runner,
    released: Option<usize>,
    stop: &AtomicBool,
) -> Result<(), Failure> {
    let mut periods = 0u32;
    runner.hold_until(
        hw,
        released,
        stop,
        &mut || {
            periods += 1;
            periods >= 50
        },
        &mut |_| {},
    )
}

impl Technician<Twin> for SimTechnician {
    fn perform(
        &mut self,
        request: Request,
        hw: &mut Twin,
        runner: &mut Runner,
        stop: &AtomicBool,
    ) -> Result<(), Failure> {
        self.act(request, hw)?;
        hold_after_action(hw, runner, request.released_wire(), stop)
    }

    fn inform(&mut self, message: &str) {
        if self.echo {
            eprintln!("videt: {message}");
        }
        self.log.push(message.to_string());
    }
}

impl super::commission::CommissionTechnician<Twin> for SimTechnician {
    fn perform_commission(
        &mut self,
        step: super::commission::CommissionStep,
        hw: &mut Twin,
    ) -> Result<(), Failure> {
        use super::commission::CommissionStep;
        match step {
            CommissionStep::ReleaseEStop => hw.set_estop_button(false),
            CommissionStep::PressEStop => hw.set_estop_button(true),
            CommissionStep::PullOutWire { ring, length_m } => {
                hw.plant_mut().set_free_length_m(ring, length_m);
            }
            // The motor winds it back; the technician only lets go.
            CommissionStep::LetGo { .. } => {}
            // The service's twin is put at rest before a procedure and its thimble connected
            // again afterwards.
            CommissionStep::DetachThimble | CommissionStep::AttachThimble => {}
        }
        self.inform(&format!("{step:?} done"));
        Ok(())
    }
}

impl super::tension::TensionTechnician<Twin> for SimTechnician {
    fn perform(&mut self, step: super::tension::TensionStep, hw: &mut Twin) -> Result<(), Failure> {
        use super::tension::TensionStep;
        let plant = hw.plant_mut();
        match step {
            TensionStep::Unload { wire } => {
                plant.detach_wire(wire);
                plant.set_free_length_m(wire, 0.3);
            }
            TensionStep::HangWeight { wire, mass_kg } => plant.hang_weight(wire, mass_kg),
            TensionStep::Finish { wire } => {
                plant.hang_weight(wire, 0.0);
                plant.set_free_length_m(wire, 0.0);
            }
        }
        self.inform(&format!("{step:?} done"));
        Ok(())
    }
}
