//! Whole-stack test: the virtual operator slides over a bas-relief built from known segments by
//! the real surface builder, rendered through the god-object proxy by the real control loop on
//! the digital twin; a new surface is swapped in mid-slide. No pop-through, no force jumps.

use std::sync::atomic::AtomicBool;

use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::Surface;
use videt_relief::{build_from_device, ReliefModel, ReliefShape};
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopSettings, LoopStats,
    WindowStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::SnapshotWriter;
use videt_service::relief_feed::relief_channel;
use videt_service::relief_scene::{
    blend_params, box_operator, box_relief, box_segments, proxy_params,
};
use videt_sim::Vec3;

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

/// The virtual operator's box slide (`box_operator`, 4.6 s) over `model_a`, `model_b` swapped in
/// at 1.8 s, through the real control loop on the twin: the loop's report and every record.
fn slide(
    config: &Config,
    model_a: &ReliefModel,
    model_b: &ReliefModel,
) -> (videt_runtime::control_loop::LoopReport, Vec<CycleRecord>) {
    let layout = videt_runtime::setup::relief_layout(config);
    let k = config.control.stiffness_n_per_m;
    let period_s = 1.0 / f64::from(config.control.rate_hz);
    let (writer, mut feed) = relief_channel(
        model_a.clone(),
        proxy_params(),
        blend_params(config),
        k,
        period_s,
    )
    .unwrap();

    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(config, 42);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(box_operator(&layout, start, 5.0));
    let rig = setup::rig(config).unwrap();
    let mut cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((SLIDE_S * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    let mut recorder = Recorder {
        records: Vec::with_capacity(10_000),
        writer,
        swap_at_cycle: swap_at_cycle(config),
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
    (report, recorder.records)
}

/// Seconds of the slide.
const SLIDE_S: f64 = 4.6;

/// The surface `r` was rendered with: the first, or the one swapped in.
fn rendered<'a>(
    r: &CycleRecord,
    first: &'a ReliefModel,
    swapped: &'a ReliefModel,
) -> &'a ReliefModel {
    if r.surface_version == 0 {
        first
    } else {
        swapped
    }
}

/// The slide's periods at full force (the ramps in and out left aside), and how many of them
/// touched the relief (asserted to be most of the slide).
fn steady_contact(records: &[CycleRecord]) -> (Vec<&CycleRecord>, usize) {
    let steady: Vec<&CycleRecord> = records
        .iter()
        .filter(|r| r.force_scale >= 1.0 && r.time.as_secs_f64() < SLIDE_S - 0.05)
        .collect();
    let in_contact = steady.iter().filter(|r| r.in_contact).count();
    assert!(
        in_contact > 2000,
        "touched the relief ({in_contact} periods)"
    );
    (steady, in_contact)
}

/// The period at which the second surface is swapped in: while the finger slides down the
/// box's edge, about 1.8 s in.
fn swap_at_cycle(config: &Config) -> u64 {
    (1.8 * f64::from(config.control.rate_hz)) as u64
}

/// The distance from `p` (inside the solid) to the surface of `model`: the least of its depth
/// along `z` and its distances, along `x` and `y` both ways, to where the surface passes
/// below it (0.1 mm steps): at a steep wall the finger may be deep along `z` yet close to the
/// wall's face.
fn distance_inside(model: &ReliefModel, p: &videt_control::Vec3) -> f64 {
    let Some(contact) = model.contact(p) else {
        return 0.0;
    };
    let mut best = contact.depth_m;
    for (dx, dy) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
        let mut d = 1e-4;
        while d < best {
            let q = videt_control::Vec3::new(p.x + dx * d, p.y + dy * d, p.z);
            if model.contact(&q).is_none() {
                best = d;
                break;
            }
            d += 1e-4;
        }
    }
    best
}

#[test]
fn operator_slides_over_a_box_relief_without_pop_through_or_force_jumps() {
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let (model_a, report) = box_relief(&layout, 0.0).unwrap();
    assert_eq!(report.constraints_kept, 8);
    // The surface swapped in mid-slide: the box top 4 mm nearer.
    let (model_b, _) = box_relief(&layout, 0.004).unwrap();

    let k = config.control.stiffness_n_per_m;
    let period_s = 1.0 / f64::from(config.control.rate_hz);
    let swap_at_cycle = swap_at_cycle(&config);
    let (report, records) = slide(&config, &model_a, &model_b);
    assert_eq!(report.final_safety, SafetyState::Normal);
    let (steady, in_contact) = steady_contact(&records);

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
        let model = rendered(r, &model_a, &model_b);
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

#[test]
fn operator_slides_over_a_stepped_relief_without_pop_through_or_force_jumps() {
    // The same outlines built with the stepped shape: the box's sides become the walls of an
    // occluding edge, the finger slides onto the top, off its cliff and back.
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let stepped = |lift_m: f64| {
        let mut params = layout.params([640, 480], [0.5, 5.0]).unwrap();
        params.shape = ReliefShape::Stepped;
        let (model, report) =
            build_from_device(&box_segments(&layout, lift_m), &[], &params).unwrap();
        assert!(report.depth_steps >= 8, "{} steps cut", report.depth_steps);
        model
    };
    let (model_a, model_b) = (stepped(0.0), stepped(0.004));
    let (report, records) = slide(&config, &model_a, &model_b);
    assert_eq!(report.final_safety, SafetyState::Normal);
    let k = config.control.stiffness_n_per_m;
    let (steady, in_contact) = steady_contact(&records);
    // No pop-through: inside the solid, the spring pushes back with at least half the finger's
    // distance to the surface (at a wall: to its face).
    let mut deepest: f64 = 0.0;
    for r in &steady {
        let p = videt_control::Vec3::from(r.position_m);
        let model = rendered(r, &model_a, &model_b);
        let distance = distance_inside(model, &p);
        deepest = deepest.max(distance);
        let spring_m = videt_control::Vec3::from(r.desired_force_n).norm() / k;
        assert!(
            spring_m >= 0.5 * distance - 0.001,
            "at t = {:.3} s the finger is {:.1} mm inside but the spring is {:.1} mm",
            r.time.as_secs_f64(),
            distance * 1e3,
            spring_m * 1e3
        );
    }
    assert!(deepest < 0.015, "deepest {:.1} mm", deepest * 1e3);
    // The proxy bounds the spring's change per period at the walls too.
    let bound = k * proxy_params().max_offset_step_m + 0.1;
    let max_step = steady
        .windows(2)
        .filter(|w| w[1].cycle == w[0].cycle + 1)
        .map(|w| (Vec3::from(w[1].desired_force_n) - Vec3::from(w[0].desired_force_n)).norm())
        .fold(0.0, f64::max);
    eprintln!(
        "stepped: contact {in_contact} periods, deepest {:.2} mm, max force step {max_step:.3} N",
        deepest * 1e3
    );
    assert!(
        max_step < bound,
        "force step {max_step:.3} N (bound {bound:.2} N)"
    );
}
