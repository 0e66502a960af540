//! Whole-stack test: the virtual operator slides over a bas-relief built from known segments by
//! the real surface builder, rendered through the god-object proxy by the real control loop on
//! the digital twin; a new surface is swapped in mid-slide. No pop-through, no force jumps.

use std::sync::atomic::AtomicBool;

use videt_control::safety::SafetyState;
use videt_control::Surface;
use videt_rt_config::Config;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopSettings, LoopStats,
    WindowStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::SnapshotWriter;
use videt_service::relief_feed::relief_channel;
use videt_service::relief_scene::{
    blend_params, box_operator, box_relief, proxy_params, ReliefLayout,
};
use videt_sim::Vec3;
use videt_vision::surface::ReliefModel;

/// Keeps every record and publishes a new surface at a given period (as the vision thread
/// would; the test publishes from the observer for determinism).
struct Recorder {
    records: Vec<CycleRecord>,
    writer: SnapshotWriter<ReliefModel>,
    swap_at_cycle: u64,
    next_model: ReliefModel,
}

impl CycleObserver for Recorder {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if self.records.len() < self.records.capacity() {
            self.records.push(*record);
        }
        if record.cycle == self.swap_at_cycle {
            let next = &self.next_model;
            self.writer.publish_with(|slot| slot.clone_from(next));
        }
    }
}

#[test]
fn operator_slides_over_a_box_relief_without_pop_through_or_force_jumps() {
    let config = Config::default();
    let layout = ReliefLayout::for_config(&config);
    let (model_a, report) = box_relief(&layout, 0.0).unwrap();
    assert_eq!(report.constraints_kept, 8);
    // The surface swapped in mid-slide: the box top 4 mm nearer.
    let (model_b, _) = box_relief(&layout, 0.004).unwrap();

    let k = config.control.stiffness_n_per_m;
    let period_s = 1.0 / f64::from(config.control.rate_hz);
    let (writer, mut feed) = relief_channel(
        model_a.clone(),
        proxy_params(),
        blend_params(&config),
        k,
        period_s,
    )
    .unwrap();

    let mut scene = videt_assembly::twin_scene::demo_scene(&config, 42);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(box_operator(&layout, start, 5.0));
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let seconds = 4.6;
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    // Swap while the finger slides down the box's edge (about 1.8 s in).
    let swap_at_cycle = (1.8 / period_s) as u64;
    let mut recorder = Recorder {
        records: Vec::with_capacity(10_000),
        writer,
        swap_at_cycle,
        next_model: model_b.clone(),
    };
    let stop = AtomicBool::new(false);
    let report = run_control_loop(
        &mut twin,
        &mut feed,
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut recorder,
        &mut LoopStats::default(),
    );
    assert_eq!(report.final_safety, SafetyState::Normal);
    let records = recorder.records;
    let steady: Vec<&CycleRecord> = records
        .iter()
        .filter(|r| r.force_scale >= 1.0 && r.time.as_secs_f64() < seconds - 0.05)
        .collect();
    let in_contact = steady.iter().filter(|r| r.in_contact).count();
    assert!(
        in_contact > 2000,
        "touched the relief ({in_contact} periods)"
    );

    // The finger slid over the box top, off its edge and back.
    let xs: Vec<f64> = steady
        .iter()
        .filter(|r| r.in_contact)
        .map(|r| r.position_m[0])
        .collect();
    let slid =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(slid > 0.05, "slid {slid} m over the relief");

    // No pop-through: wherever the finger is inside the solid, the rendered spring pushes it
    // back with at least the stiffness times its distance to the surface (the depth along z
    // times the steepest face's |n_z|, less a small tolerance).
    let min_nz = model_a
        .vertex_normals()
        .iter()
        .chain(model_b.vertex_normals())
        .map(|n| n[2].abs())
        .fold(1.0, f64::min);
    let mut max_depth: f64 = 0.0;
    for r in &steady {
        let p = videt_control::Vec3::from(r.position_m);
        let model = if r.surface_version == 0 {
            &model_a
        } else {
            &model_b
        };
        let depth = model.contact(&p).map_or(0.0, |c| c.depth_m);
        max_depth = max_depth.max(depth);
        let spring_m = videt_control::Vec3::from(r.desired_force_n).norm() / k;
        assert!(
            spring_m >= 0.5 * depth * min_nz - 0.001,
            "at t = {:.3} s the finger is {:.1} mm inside but the spring is {:.1} mm",
            r.time.as_secs_f64(),
            depth * 1e3,
            spring_m * 1e3
        );
    }
    assert!(max_depth < 0.015, "deepest {:.1} mm", max_depth * 1e3);

    // No force jumps, also across the swap.
    let mut max_step: f64 = 0.0;
    let mut at = 0.0;
    for w in steady.windows(2) {
        let (a, b) = (w[0], w[1]);
        if b.cycle != a.cycle + 1 {
            continue;
        }
        let step = (Vec3::from(b.desired_force_n) - Vec3::from(a.desired_force_n)).norm();
        if step > max_step {
            max_step = step;
            at = b.time.as_secs_f64();
        }
    }
    let swapped = records.iter().any(|r| r.surface_version == 1);
    assert!(swapped, "the new surface was rendered");
    eprintln!(
        "contact {in_contact} periods, slid {:.1} mm, deepest {:.2} mm, max force step {:.3} N/period at {at:.3} s",
        slid * 1e3,
        max_depth * 1e3,
        max_step
    );
    // Around the swap the blend bounds the step (0.05 N from the swap plus the finger's own
    // motion).
    let swap_t = swap_at_cycle as f64 * period_s;
    let swap_step = steady
        .windows(2)
        .filter(|w| w[1].cycle == w[0].cycle + 1)
        .filter(|w| (w[1].time.as_secs_f64() - swap_t).abs() < 0.01)
        .map(|w| (Vec3::from(w[1].desired_force_n) - Vec3::from(w[0].desired_force_n)).norm())
        .fold(0.0, f64::max);
    eprintln!("max force step within 10 ms of the swap: {swap_step:.3} N/period");
    assert!(swap_step < 0.15, "swap force step {swap_step:.3} N");
    // Elsewhere the proxy bounds the spring's change to K * 0.5 mm = 0.4 N per period (where
    // the finger, a few millimetres deep, passes under the box's convex edge and the proxy
    // changes face), plus the finger's own motion.
    let bound = k * proxy_params().max_offset_step_m + 0.1;
    assert!(
        max_step < bound,
        "force step {max_step:.3} N at t = {at:.3} s (bound {bound:.2} N)"
    );
}
