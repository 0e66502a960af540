//! One full control step — forward kinematics, velocity, a plane query, contact force, field,
//! projection, PI — per algorithm, in contact with a wall whose normal is outside the wire cone
//! (the expensive case: the projection runs), and in free space.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use videt_control::{
    Algorithm, ControlParams, ControlStep, ForceField, FreeSpace, Plane, Rig3, StepInput,
    StepOutput, TensionPiGains, Vec3,
};

fn bench_control_step(c: &mut Criterion) {
    let rig = Rig3::new([
        Vec3::zeros(),
        Vec3::new(0.37, 0.0, 0.0),
        Vec3::new(0.185, 0.30, 0.0),
    ])
    .unwrap();
    // A wall facing the user, tilted: its push is outside the wire cone.
    let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.4, 0.1, 1.0)).unwrap();
    let p = Vec3::new(0.2, 0.12, 0.2);
    let input = StepInput {
        lengths_m: rig.inverse(&p),
        length_rates_m_s: [0.01, -0.02, 0.005],
        measured_tension_n: [1.0, 2.0, 0.5],
        dt_s: 1e-3,
        render_forces: true,
        force_scale: 1.0,
    };
    let mut group = c.benchmark_group("control_step");
    for algorithm in Algorithm::ALL {
        let mut params = ControlParams::paper_defaults(TensionPiGains {
            feedforward_nm_per_n: 0.0008,
            kp_nm_per_n: 0.0005,
            ki_nm_per_n_s: 0.02,
            torque_limit_nm: 0.02,
        });
        params.algorithm = algorithm;
        if matches!(algorithm, Algorithm::F1 | Algorithm::F2 | Algorithm::Qp) {
            params.field = ForceField::towards_frame(1.0);
        }
        let mut step = ControlStep::new(rig, params);
        let mut out = StepOutput::default();
        step.update(&input, &wall, &mut out);
        assert!(out.contact.is_some() && out.distribution.projected);
        group.bench_function(format!("contact_projected/{}", algorithm.name()), |b| {
            b.iter(|| {
                step.update(black_box(&input), black_box(&wall), &mut out);
                black_box(&out);
            })
        });
        group.bench_function(format!("free_space/{}", algorithm.name()), |b| {
            b.iter(|| {
                step.update(black_box(&input), black_box(&FreeSpace), &mut out);
                black_box(&out);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_control_step);
criterion_main!(benches);
