//! Whole-stack tests of auto-initialization and wire replacement: the real procedure, runner and
//! session code on the digital twin (simulated clock), with encoder quantization, arbitrary
//! encoder offsets and noisy, offset, gain-erring tension sensors.

use std::sync::atomic::AtomicBool;
use videt_assembly::WiremanTwin as Twin;

use videt_config::Config;
use videt_control::autoinit::{Failure, Limit, Plan, Procedure, Status};
use videt_service::init::params::procedure_params;
use videt_service::init::runner::Runner;
use videt_service::init::session::{self, run_settings, FlowContext, InitError, InitOutcome};
use videt_service::init::twin::{rest_twin, SimFault, SimTechnician, TwinSetup};
use videt_sim::{SensorModel, TwinFault, Vec3};

fn setup(guides: [[f64; 2]; 3], seed: u64) -> TwinSetup {
    TwinSetup {
        guides_m: core::array::from_fn(|i| Vec3::new(guides[i][0], guides[i][1], 0.0)),
        seed,
        sensors: SensorModel {
            seed,
            noise_std_n: 0.03,
            ..SensorModel::default()
        },
        new_wire_length_m: 1.5,
        faults: Vec::new(),
    }
}

fn true_sides(g: &[Vec3; 3]) -> [f64; 3] {
    [
        (g[1] - g[0]).norm(),
        (g[2] - g[0]).norm(),
        (g[2] - g[1]).norm(),
    ]
}

/// The truth moved into the paper's frame (g0 at the origin, g1 on +x, g2 at y > 0).
fn true_guides_in_papers_frame(g: &[Vec3; 3]) -> [Vec3; 3] {
    let ex = (g[1] - g[0]).normalize();
    let mut ey = Vec3::new(-ex.y, ex.x, 0.0);
    if (g[2] - g[0]).dot(&ey) < 0.0 {
        ey = -ey;
    }
    core::array::from_fn(|i| {
        let d = g[i] - g[0];
        Vec3::new(d.dot(&ex), d.dot(&ey), 0.0)
    })
}

fn run_init(config: &Config, s: &TwinSetup) -> (Twin, Result<InitOutcome, InitError>) {
    let mut twin = rest_twin(config, s);
    let mut tech = SimTechnician::new(s);
    let mut runner = Runner::new(run_settings(config));
    session::start(&mut twin).unwrap();
    let stop = AtomicBool::new(false);
    let ctx = FlowContext {
        config,
        source: "twin",
        stop: &stop,
    };
    let r = session::initialize(&mut twin, &mut tech, &mut runner, &ctx);
    (twin, r)
}

#[test]
fn sides_and_guides_match_the_truth_on_rigs_the_test_picks() {
    let config = Config::default();
    let rigs = [
        [[0.03, -0.02], [0.42, 0.05], [0.16, 0.31]],
        [[-0.10, 0.10], [0.25, -0.05], [0.20, 0.35]],
        // A wide, flat frame and a narrow, tall one.
        [[0.0, 0.0], [0.55, 0.02], [0.30, 0.22]],
        [[0.05, 0.0], [0.28, -0.01], [0.12, 0.42]],
    ];
    for (k, rig) in rigs.iter().enumerate() {
        let s = setup(*rig, 100 + k as u64);
        let (twin, r) = run_init(&config, &s);
        let out = r.unwrap_or_else(|e| panic!("rig {k}: {e}"));
        let truth = true_sides(&s.guides_m);
        let guides = true_guides_in_papers_frame(&s.guides_m);
        let measured = out.triangle.rig.guides_m();
        let side_err: Vec<f64> = (0..3)
            .map(|i| (out.triangle.sides_m[i] - truth[i]).abs())
            .collect();
        let guide_err: Vec<f64> = (0..3).map(|i| (measured[i] - guides[i]).norm()).collect();
        println!(
            "rig {k}: side errors {:.4?} mm, guide errors {:.4?} mm, residuals {:.4?} mm",
            side_err.iter().map(|e| e * 1e3).collect::<Vec<_>>(),
            guide_err.iter().map(|e| e * 1e3).collect::<Vec<_>>(),
            out.triangle
                .residuals_m
                .iter()
                .map(|e| e * 1e3)
                .collect::<Vec<_>>()
        );
        for e in &side_err {
            assert!(*e < 0.5e-3, "rig {k}: side error {e}");
        }
        for e in &guide_err {
            assert!(*e < 1e-3, "rig {k}: guide error {e}");
        }
        // The encoder zeros found are the twin's (within 0.1 mm of wire).
        let truth_offsets = twin.encoder_offset_counts();
        let m = videt_runtime::setup::transmission(&config).metres_per_count();
        for i in 0..3 {
            let e = (out.zero_counts[i] - truth_offsets[i]) as f64 * m;
            assert!(e.abs() < 0.1e-3, "rig {k} wire {i}: zero off by {e} m");
        }
        assert!(out.workspace.points > 0);
    }
}

/// Run an initialization with `faults` on a rig the test picks; return the failure and the twin.
fn failing(config: &Config, guides: [[f64; 2]; 3], faults: Vec<SimFault>) -> (Twin, InitError) {
    let mut s = setup(guides, 21);
    s.faults = faults;
    let (twin, r) = run_init(config, &s);
    match r {
        Ok(o) => panic!("expected a failure, got sides {:?}", o.triangle.sides_m),
        Err(e) => (twin, e),
    }
}

const RIG: [[f64; 2]; 3] = [[0.01, 0.02], [0.39, -0.01], [0.21, 0.33]];

/// After a failure the motors hold every wire at most at the pay-out (minimum) tension: no
/// winding force is left (a wire still winding fast gets less, from the speed governor).
fn assert_minimum_tension(config: &Config, twin: &Twin) {
    let tr = videt_runtime::setup::transmission(config);
    let pay_out = tr.torque_for_tension(config.autoinit.pay_out_tension_n);
    for (i, t) in twin.applied_torque_nm().iter().enumerate() {
        assert!(
            *t >= 0.0 && *t <= pay_out + 1e-12,
            "wire {i}: torque {t} N·m, pay-out {pay_out} N·m"
        );
    }
    assert!(
        twin.drives_enabled(),
        "the drives stay on, holding the wires"
    );
}

fn slip_counts(config: &Config, mm: f64) -> i64 {
    (mm * 1e-3 / videt_runtime::setup::transmission(config).metres_per_count()).round() as i64
}

#[test]
fn homing_finds_each_detached_wires_encoder_zero() {
    let config = Config::default();
    let s = setup([[0.0, 0.01], [0.38, 0.0], [0.2, 0.3]], 33);
    let mut twin = rest_twin(&config, &s);
    // Some wire hanging out of each ring, as after the wearer took the thimble off.
    for (i, hanging) in [0.05, 0.2, 0.12].iter().enumerate() {
        twin.plant_mut().fit_new_wire(i, *hanging, 1.5);
    }
    let mut runner = Runner::new(run_settings(&config));
    session::start(&mut twin).unwrap();
    let mut homing = Procedure::new(procedure_params(&config), Plan::Home { wires: [true; 3] });
    let status = runner.run(
        &mut twin,
        &mut homing,
        &AtomicBool::new(false),
        &mut |_, _| {},
    );
    assert_eq!(status, Status::Finished);
    let m = videt_runtime::setup::transmission(&config).metres_per_count();
    let truth = twin.encoder_offset_counts();
    for i in 0..3 {
        let e = (homing.homed_zero_counts()[i] - truth[i]) as f64 * m;
        println!("wire {i}: homed zero off by {:.4} mm", e * 1e3);
        assert!(e.abs() < 0.1e-3, "wire {i}: {e} m");
    }
    // Every wire is left at the pay-out tension against its ring.
    let t = twin.plant().tension_n();
    for ti in t {
        assert!(
            (ti - config.autoinit.pay_out_tension_n).abs() < 0.05,
            "{t:?}"
        );
    }
}

#[test]
fn every_failure_mode_has_its_own_error() {
    let config = Config::default();

    let (twin, e) = failing(&config, RIG, vec![SimFault::Disconnected(1)]);
    assert!(
        matches!(
            e,
            InitError::Procedure(Failure::NotConnected { wire: 1, .. })
        ),
        "{e}"
    );
    assert_eq!(e.exit_code(), 12);
    assert_minimum_tension(&config, &twin);

    let (twin, e) = failing(&config, RIG, vec![SimFault::Disconnected(0)]);
    assert!(
        matches!(
            e,
            InitError::Procedure(Failure::NotConnected { wire: 0, .. })
        ),
        "{e}"
    );
    assert_minimum_tension(&config, &twin);

    let mut quick = config.clone();
    quick.autoinit.max_wind_travel_m = 0.6;
    let (twin, e) = failing(
        &quick,
        RIG,
        vec![SimFault::After(1.0, TwinFault::BreakWire(0))],
    );
    assert!(
        matches!(
            e,
            InitError::Procedure(Failure::TensionNeverRose { wire: 0, .. })
        ),
        "{e}"
    );
    assert_eq!(e.exit_code(), 13);
    assert!(e.to_string().contains("broken or slipping"), "{e}");
    assert_minimum_tension(&quick, &twin);

    let (twin, e) = failing(
        &config,
        RIG,
        vec![SimFault::After(2.0, TwinFault::PressEStop)],
    );
    assert!(
        matches!(e, InitError::Procedure(Failure::EmergencyStop)),
        "{e}"
    );
    assert_eq!(e.exit_code(), 10);
    assert!(!twin.drives_enabled(), "an e-stop powers the drives off");

    let (twin, e) = failing(
        &config,
        RIG,
        vec![SimFault::After(
            7.0,
            TwinFault::SlipWire(2, slip_counts(&config, 3.0)),
        )],
    );
    assert!(
        matches!(e, InitError::Procedure(Failure::SidesDisagree { .. })),
        "{e}"
    );
    assert_eq!(e.exit_code(), 14);
    assert_minimum_tension(&config, &twin);

    let (twin, e) = failing(
        &config,
        RIG,
        vec![SimFault::After(2.0, TwinFault::FailTensionSensor(1))],
    );
    assert!(
        matches!(e, InitError::Procedure(Failure::SensorFault)),
        "{e}"
    );
    assert_eq!(e.exit_code(), 18);
    assert_minimum_tension(&config, &twin);

    let mut short = config.clone();
    short.autoinit.max_length_m = 0.3;
    let (twin, e) = failing(&short, RIG, vec![]);
    assert!(
        matches!(
            e,
            InitError::Procedure(Failure::LimitHit {
                limit: Limit::Length { .. },
                ..
            })
        ),
        "{e}"
    );
    assert_eq!(e.exit_code(), 11);
    assert_minimum_tension(&short, &twin);

    let mut hasty = config.clone();
    hasty.autoinit.stage_timeout_s = 1.0;
    let (twin, e) = failing(&hasty, RIG, vec![]);
    assert!(
        matches!(e, InitError::Procedure(Failure::Timeout { wire: 0, .. })),
        "{e}"
    );
    assert_eq!(e.exit_code(), 19);
    assert_minimum_tension(&hasty, &twin);
}

#[test]
fn collinear_guides_are_reported_as_a_degenerate_triangle() {
    let config = Config::default();
    let (twin, e) = failing(&config, [[0.0, 0.0], [0.2, 0.004], [0.4, 0.0]], vec![]);
    assert!(
        matches!(e, InitError::Procedure(Failure::DegenerateTriangle { .. })),
        "{e}"
    );
    assert_eq!(e.exit_code(), 16);
    assert_minimum_tension(&config, &twin);
}

#[test]
fn a_replaced_wire_is_homed_checked_and_the_rig_reinitialized() {
    let config = Config::default();
    let s = setup([[0.02, 0.0], [0.40, 0.03], [0.19, 0.32]], 9);
    let stop = AtomicBool::new(false);
    let ctx = FlowContext {
        config: &config,
        source: "twin",
        stop: &stop,
    };
    let required = session::required_wire_length_m(&config, None);
    let mut twin = rest_twin(&config, &s);
    let mut tech = SimTechnician::new(&s);
    let mut runner = Runner::new(run_settings(&config));
    session::start(&mut twin).unwrap();
    let out = session::replace_wire(&mut twin, &mut tech, &mut runner, &ctx, 1, required).unwrap();
    let truth = true_sides(&s.guides_m);
    for k in 0..3 {
        assert!((out.triangle.sides_m[k] - truth[k]).abs() < 0.5e-3);
    }

    // A yarn shorter than the workspace needs is refused before anything is measured.
    let mut s = s.clone();
    s.new_wire_length_m = required - 0.05;
    let mut twin = rest_twin(&config, &s);
    let mut tech = SimTechnician::new(&s);
    let mut runner = Runner::new(run_settings(&config));
    session::start(&mut twin).unwrap();
    let e =
        session::replace_wire(&mut twin, &mut tech, &mut runner, &ctx, 2, required).unwrap_err();
    assert!(matches!(e, InitError::WireTooShort { wire: 2, .. }), "{e}");
    assert_eq!(e.exit_code(), 21);
}

/// Calibrate wire 1's sensor with 0.5 kg on a fresh twin, `tech` doing the steps, and check
/// the offset and gain against the twin's sensor.
fn calibrate_wire_1<T: videt_service::init::tension::TensionTechnician<Twin>>(tech: &mut T) {
    let config = Config::default();
    let s = setup(RIG, 4);
    let mut twin = rest_twin(&config, &s);
    let mut runner = Runner::new(run_settings(&config));
    session::start(&mut twin).unwrap();
    let p = videt_service::init::tension::calibrate_tension(
        &mut twin,
        tech,
        &mut runner,
        1,
        0.5,
        &AtomicBool::new(false),
    )
    .unwrap();
    let (offset, gain_error) = (s.sensors.offset_n[1], s.sensors.gain_error[1]);
    assert!((p.offset_n - offset).abs() < 0.005, "{p:?}");
    assert!((p.gain - 1.0 / (1.0 + gain_error)).abs() < 0.002, "{p:?}");
}

#[test]
fn tension_calibration_recovers_the_sensor_offset_and_gain() {
    calibrate_wire_1(&mut SimTechnician::new(&setup(RIG, 4)));
}

/// A person: each step is done some time after it is asked for (200 periods), and confirmed
/// later still (400 periods after that). Records how far the weight pulled the wire out while
/// it was being hung and until it was confirmed.
struct SlowTechnician {
    polls: u32,
    hung_at_free_length_m: f64,
    pulled_out_by_weight_m: f64,
}

impl videt_service::init::tension::TensionTechnician<Twin> for SlowTechnician {
    fn perform(
        &mut self,
        _step: videt_service::init::tension::TensionStep,
        _hw: &mut Twin,
    ) -> Result<(), Failure> {
        self.polls = 0;
        Ok(())
    }

    fn step_done(
        &mut self,
        step: videt_service::init::tension::TensionStep,
        hw: &mut Twin,
    ) -> bool {
        use videt_service::init::tension::TensionStep;
        self.polls += 1;
        let plant = hw.plant_mut();
        if self.polls == 200 {
            match step {
                TensionStep::Unload { wire } => {
                    plant.detach_wire(wire);
                    plant.set_free_length_m(wire, 0.3);
                }
                TensionStep::HangWeight { wire, mass_kg } => {
                    plant.hang_weight(wire, mass_kg);
                    self.hung_at_free_length_m = plant.free_length_m()[wire];
                }
                TensionStep::Finish { wire } => plant.hang_weight(wire, 0.0),
            }
        }
        if let (TensionStep::HangWeight { wire, .. }, true) = (step, self.polls > 200) {
            let out = plant.free_length_m()[wire] - self.hung_at_free_length_m;
            self.pulled_out_by_weight_m = self.pulled_out_by_weight_m.max(out);
        }
        self.polls >= 600
    }
}

/// With a person doing the steps at their own pace, the wires are held meanwhile: the weight,
/// once hung, is caught by the motor within a few centimetres instead of falling, and the
/// calibration is as accurate as with steps done at once.
#[test]
fn tension_calibration_holds_the_wire_while_a_person_hangs_the_weight() {
    let mut tech = SlowTechnician {
        polls: 0,
        hung_at_free_length_m: 0.0,
        pulled_out_by_weight_m: 0.0,
    };
    calibrate_wire_1(&mut tech);
    assert!(
        tech.pulled_out_by_weight_m < 0.05,
        "the weight pulled {:.3} m of wire out",
        tech.pulled_out_by_weight_m
    );
}

/// Accuracy over many rigs (run with `--ignored --nocapture` for the figures): random frames
/// between 0.25 and 0.6 m across, random connection points and seeds.
#[test]
#[ignore = "a sweep for the accuracy figures; the regular tests cover four rigs"]
fn accuracy_sweep_over_random_rigs() {
    use rand::{Rng, SeedableRng};
    let config = Config::default();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2026);
    let (mut worst_side, mut worst_guide, mut worst_residual) = (0.0_f64, 0.0_f64, 0.0_f64);
    let mut done = 0;
    while done < 20 {
        let g = [
            [rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05)],
            [rng.random_range(0.25..0.6), rng.random_range(-0.08..0.08)],
            [rng.random_range(0.05..0.45), rng.random_range(0.2..0.45)],
        ];
        let s = setup(g, 1000 + done);
        if videt_control::Rig3::new(s.guides_m).is_err() {
            continue;
        }
        let (_, r) = run_init(&config, &s);
        let out = r.unwrap_or_else(|e| panic!("rig {g:?}: {e}"));
        let truth = true_sides(&s.guides_m);
        let guides = true_guides_in_papers_frame(&s.guides_m);
        for k in 0..3 {
            worst_side = worst_side.max((out.triangle.sides_m[k] - truth[k]).abs());
            worst_guide = worst_guide.max((out.triangle.rig.guides_m()[k] - guides[k]).norm());
        }
        for r in out.triangle.residuals_m {
            worst_residual = worst_residual.max(r.abs());
        }
        done += 1;
    }
    println!(
        "20 random rigs: worst side error {:.4} mm, worst guide error {:.4} mm, worst residual {:.4} mm",
        worst_side * 1e3,
        worst_guide * 1e3,
        worst_residual * 1e3
    );
    assert!(worst_side < 0.5e-3 && worst_guide < 1e-3);
}
