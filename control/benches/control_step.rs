//! One full control step — forward kinematics, velocity, a plane query, contact force, field,
//! projection, PI — per device and algorithm, in contact with a wall whose normal is outside the wire cone
//! (the expensive case: the projection runs), and in free space; and P2 with the default
//! rendering's additions (the tension integral's speed gate, the wires' stretch correction).

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use videt_control::{
    project, Algorithm, ControlParams, ControlStep, ForceField, ForceLimits, FreeSpace,
    PlanarDevice, Plane, PolarDevice, Projection, Rig3, Rig4, StepInput, StepOutput,
    TensionPiGains, Vec3, WireDevice, WireMap, WireStretch,
};

fn bench_device<const N: usize, D: WireDevice<N>>(c: &mut Criterion, device: D, p: Vec3) {
    // A wall facing the user, tilted: on the cone devices its push is outside the wire cone.
    let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.4, 0.1, 1.0)).unwrap();
    let p = device.constrain(&p);
    let input = StepInput {
        lengths_m: device.inverse(&p),
        length_rates_m_s: core::array::from_fn(|i| 0.01 - 0.015 * i as f64),
        angles_rad: device.passive_angles(&p),
        angle_rates_rad_s: [0.05, -0.02],
        measured_tension_n: core::array::from_fn(|i| 1.0 + 0.5 * i as f64),
        dt_s: 1e-3,
        render_forces: true,
        force_scale: 1.0,
    };
    let mut group = c.benchmark_group(format!("control_step/{}", D::KIND.name()));
    for algorithm in Algorithm::ALL {
        let mut params =
            ControlParams::paper_defaults(TensionPiGains::pi_only(0.0008, 0.0005, 0.02, 0.02));
        params.algorithm = algorithm;
        if matches!(algorithm, Algorithm::F1 | Algorithm::F2 | Algorithm::Qp) {
            params.field = ForceField::towards_frame(1.0);
        }
        let mut step = ControlStep::new(device, params);
        let mut out = StepOutput::default();
        step.update(&input, &wall, &mut out);
        assert!(out.contact.is_some(), "{:?} {algorithm:?}", D::KIND);
        group.bench_function(format!("contact/{}", algorithm.name()), |b| {
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
    // P2 as configured by default: the integral gated by its wire's speed, the stretch corrected
    // (against plain P2 above: what they cost).
    let mut params = ControlParams::paper_defaults(TensionPiGains {
        integral_speed_gate_m_s: 0.003,
        ..TensionPiGains::pi_only(0.0008, 0.0005, 0.02, 0.02)
    });
    params.stretch = WireStretch {
        axial_stiffness_n: 8000.0,
        inside_length_m: 0.12,
    };
    let mut step = ControlStep::new(device, params);
    let mut out = StepOutput::default();
    group.bench_function("contact/P2_gated_stretch", |b| {
        b.iter(|| {
            step.update(black_box(&input), black_box(&wall), &mut out);
            black_box(&out);
        })
    });
    group.finish();
}

/// One step per device and algorithm, in contact with the tilted wall and in free space.
fn bench_control_step(c: &mut Criterion) {
    let rig = Rig3::new([
        Vec3::zeros(),
        Vec3::new(0.37, 0.0, 0.0),
        Vec3::new(0.185, 0.30, 0.0),
    ])
    .unwrap();
    let p = Vec3::new(0.2, 0.12, 0.2);
    bench_device(c, rig, p);
    bench_device(c, PlanarDevice::paper_prototype(), p);
    bench_device(c, PolarDevice::at_origin(), p);
    bench_device(c, Rig4::cube_frame(), p);
}

/// The projections alone over 256 mixed cases (positions over and beside the guide triangle,
/// targets in every direction, some beyond t_max): the average cost per call including the
/// harder cases of the QP search. Reported per batch of 256 calls.
fn bench_projection_mix(c: &mut Criterion) {
    let rig = Rig3::new([
        Vec3::zeros(),
        Vec3::new(0.37, 0.0, 0.0),
        Vec3::new(0.185, 0.30, 0.0),
    ])
    .unwrap();
    // Deterministic pseudo-random cases (xorshift), fixed seed.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut cases: Vec<(WireMap<3>, Vec3)> = Vec::new();
    while cases.len() < 256 {
        let p = Vec3::new(
            -0.2 + 0.8 * next(),
            -0.2 + 0.7 * next(),
            0.05 + 0.5 * next(),
        );
        let f = Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5) * 40.0;
        if let Some(map) = rig.wire_map(&p) {
            cases.push((map, f));
        }
    }
    let limits = ForceLimits {
        t_min_n: 0.3,
        t_max_n: 15.0,
    };
    let mut group = c.benchmark_group("projection_mix_256");
    for (name, projection) in [
        ("P1", Projection::ClampNegative),
        ("P2", Projection::ExactAlongNormal),
        ("QP", Projection::NormalFirstNearest),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for (map, f) in &cases {
                    sum += project(black_box(map), black_box(f), projection, &limits).tensions_n[0];
                }
                black_box(sum)
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_control_step, bench_projection_mix);
criterion_main!(benches);
