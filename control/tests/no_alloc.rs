//! The control step allocates nothing: a counting global allocator around many steps, for every
//! device and every algorithm, in contact and in free space.

use videt_control::{
    Algorithm, ControlParams, ControlStep, ForceField, FreeSpace, PlanarDevice, Plane, PolarDevice,
    Rig3, Rig4, StepInput, StepOutput, TensionPiGains, Vec3, WireDevice,
};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

fn params(algorithm: Algorithm) -> ControlParams {
    let mut params = ControlParams::paper_defaults(TensionPiGains {
        feedforward_nm_per_n: 0.0008,
        kp_nm_per_n: 0.0005,
        ki_nm_per_n_s: 0.02,
        torque_limit_nm: 0.02,
        speed_gain_nm_s_per_m: 0.005,
        slack_tension_n: 0.15,
        takeup_speed_m_s: 0.15,
        max_winding_speed_m_s: 0.6,
        integral_speed_gate_m_s: f64::INFINITY,
    });
    params.algorithm = algorithm;
    params.damping_n_s_per_m = 2.0;
    if matches!(algorithm, Algorithm::F1 | Algorithm::F2 | Algorithm::Qp) {
        params.field = ForceField::towards_frame(1.5);
    }
    params
}

/// Steps `device` along a path from free space into a tilted wall, for every algorithm, and
/// says how many periods were in contact; panics if anything was allocated or freed.
fn steps_without_allocating<const N: usize, D: WireDevice<N>>(device: D) -> usize {
    let wall = Plane::new(Vec3::new(0.0, 0.0, 0.3), Vec3::new(0.3, 0.1, 1.0)).unwrap();
    // Inputs prepared before counting: a path through free space and into the wall.
    let inputs: Vec<StepInput<N>> = (0..200)
        .map(|k| {
            let s = k as f64 / 200.0;
            let p = device.constrain(&Vec3::new(0.05 + 0.3 * s, 0.05 + 0.2 * s, 0.33 - 0.18 * s));
            StepInput {
                lengths_m: device.inverse(&p),
                length_rates_m_s: core::array::from_fn(|i| 0.01 - 0.01 * i as f64),
                angles_rad: device.passive_angles(&p),
                angle_rates_rad_s: [0.05, -0.02],
                measured_tension_n: core::array::from_fn(|i| 1.0 + 0.5 * i as f64),
                dt_s: 1e-3,
                render_forces: k % 50 != 0,
                force_scale: 1.0,
            }
        })
        .collect();
    let mut steps: Vec<ControlStep<N, D>> = Algorithm::ALL
        .iter()
        .map(|&algorithm| ControlStep::new(device, params(algorithm)))
        .collect();
    let mut out = StepOutput::default();

    let mut contacts = 0usize;
    let before = videt_testkit::this_thread();
    for step in steps.iter_mut() {
        for input in &inputs {
            step.update(input, &wall, &mut out);
            contacts += usize::from(out.contact.is_some());
            step.update(input, &FreeSpace, &mut out);
        }
    }
    let after = videt_testkit::this_thread();
    assert_eq!(
        after,
        before,
        "{:?}: the control step allocated or freed",
        D::KIND
    );
    // The steps did something: the last one ended with finite torques.
    assert!(out.torque_nm.iter().all(|t| t.is_finite()));
    contacts
}

#[test]
fn control_step_does_not_allocate_on_any_device() {
    // The counter sees an allocation made on this thread.
    let (probe, counts) = videt_testkit::count_allocations(|| std::hint::black_box(Box::new(7u64)));
    drop(probe);
    assert_eq!(counts.allocations, 1);

    let rig3 = Rig3::new([
        Vec3::zeros(),
        Vec3::new(0.37, 0.0, 0.0),
        Vec3::new(0.185, 0.30, 0.0),
    ])
    .unwrap();
    for (name, contacts) in [
        ("wireman3", steps_without_allocating(rig3)),
        (
            "planar2",
            steps_without_allocating(PlanarDevice::paper_prototype()),
        ),
        ("polar1", steps_without_allocating(PolarDevice::at_origin())),
        ("spidar4", steps_without_allocating(Rig4::cube_frame())),
    ] {
        assert!(
            contacts > 100,
            "{name}: the path goes into the wall ({contacts} contacts)"
        );
    }
}
