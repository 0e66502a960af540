//! Whole-stack test: the bas-relief of a real stereo pair (the committed demo pair) built by the
//! real stereo pipeline and surface builder, rendered through the god-object proxy by the real
//! control loop on the digital twin (simulated clock), while the region under the finger is
//! re-matched and merged into the relief ten times a second. The virtual operator presses into
//! the relief and sweeps across it: it touches it, never pops through, the swaps of the live
//! updates stay within the blend's force-step bound, and no safe state is entered.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_relief::ReliefModel;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, CycleObserver, LoopControl, LoopSettings, LoopStats,
    WindowStats,
};
use videt_runtime::cycle::{CycleRecord, WireZero};
use videt_runtime::setup;
use videt_runtime::snapshot::SnapshotWriter;
use videt_service::relief_feed::relief_channel;
use videt_service::relief_scene::{blend_params, proxy_params, sweep_operator, SweepPath};
use videt_service::stereo_relief::{LiveSettings, StereoPair, StereoRelief};
use videt_sim::Vec3;

/// The vision thread, run from the observer for determinism: every `every_cycles` periods it
/// re-matches the region under the finger and publishes the rebuilt relief; every
/// `full_every_cycles` it runs the whole image instead.
struct LiveVision {
    records: Vec<CycleRecord>,
    relief: StereoRelief,
    writer: SnapshotWriter<ReliefModel>,
    every_cycles: u64,
    full_every_cycles: u64,
    full_refreshes: usize,
    /// The model of each published version (index = version).
    models: Vec<ReliefModel>,
    update_times: Vec<Duration>,
    /// Cycle each version was published at.
    published_at: Vec<u64>,
}

impl CycleObserver for LiveVision {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if self.records.len() < self.records.capacity() {
            self.records.push(*record);
        }
        if record.cycle == 0 || !record.cycle.is_multiple_of(self.every_cycles) {
            return;
        }
        if record.cycle.is_multiple_of(self.full_every_cycles) {
            let (model, _) = self.relief.refresh_full().expect("a whole-image run");
            self.writer.publish_with(|slot| slot.clone_from(&model));
            self.models.push(model);
            self.published_at.push(record.cycle);
            self.full_refreshes += 1;
            return;
        }
        let update = self
            .relief
            .update_around(record.position_m, record.velocity_m_s)
            .expect("a live update of the demo pair");
        if let Some((model, update)) = update {
            self.writer.publish_with(|slot| slot.clone_from(&model));
            self.models.push(model);
            self.update_times.push(update.total_time());
            self.published_at.push(record.cycle);
        }
    }
}

fn force_step(a: &CycleRecord, b: &CycleRecord) -> f64 {
    (Vec3::from(b.desired_force_n) - Vec3::from(a.desired_force_n)).norm()
}

#[test]
fn operator_sweeps_a_live_relief_from_a_real_stereo_pair() {
    let config = Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let live = LiveSettings {
        update_period_s: 0.1,
        ..LiveSettings::default()
    };
    let (relief, model, initial) =
        StereoRelief::build(StereoPair::demo().unwrap(), &layout, live).unwrap();
    assert!(
        initial.report.constraints_kept >= 40,
        "{} matched segments used",
        initial.report.constraints_kept
    );

    let k = config.control.stiffness_n_per_m;
    let period_s = 1.0 / f64::from(config.control.rate_hz);
    let blend = blend_params(&config);
    let (writer, mut feed) =
        relief_channel(model.clone(), proxy_params(), blend, k, period_s).unwrap();

    let mut scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 7);
    let start = scene.twin.plant().position_m();
    let path = SweepPath::default();
    let (operator, _) = sweep_operator(&layout, &model, start, &path);
    scene.twin.set_operator(operator);
    let rig = setup::rig(&config).unwrap();
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let seconds = 5.5;
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: Some((seconds * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let mut twin = scene.twin;
    start_hardware(&mut twin).unwrap();
    let mut vision = LiveVision {
        records: Vec::with_capacity(6000),
        relief,
        writer,
        every_cycles: (live.update_period_s / period_s).round() as u64,
        full_every_cycles: 2000,
        full_refreshes: 0,
        models: vec![model],
        update_times: Vec::new(),
        published_at: vec![0],
    };
    let stop = AtomicBool::new(false);
    let report = run_control_loop(
        &mut twin,
        &mut feed,
        &mut cycle,
        &settings,
        &mut LoopControl::stop_flag(&stop),
        &mut vision,
        &mut LoopStats::default(),
    );

    // No safe state, ever.
    assert_eq!(report.final_safety, SafetyState::Normal);
    let records = &vision.records;
    assert!(records.len() > 5000, "{} periods", records.len());
    if let Some(r) = records.iter().find(|r| r.safety != SafetyState::Normal) {
        panic!(
            "safe state {:?} at t = {:.3} s",
            r.safety,
            r.time.as_secs_f64()
        );
    }
    assert!(
        records.iter().all(|r| !r.surface_stale),
        "the live relief never went stale"
    );

    // Several live updates were rendered.
    let updates = vision.update_times.len();
    let rendered_versions = {
        let mut v: Vec<u64> = records.iter().map(|r| r.surface_version).collect();
        v.dedup();
        v.len()
    };
    assert!(updates >= 20, "{updates} live updates");
    assert_eq!(vision.full_refreshes, 2, "whole-image runs at 2 s and 4 s");
    assert!(
        rendered_versions >= 20,
        "{rendered_versions} versions rendered"
    );

    // Contact: once the hand has reached the surface (1.2 s), the finger touches the relief with
    // a real force for most of the sweep, and slides across it.
    let steady: Vec<&CycleRecord> = records
        .iter()
        .filter(|r| r.force_scale >= 1.0 && r.time.as_secs_f64() < seconds - 0.05)
        .collect();
    let sweeping: Vec<&&CycleRecord> = steady
        .iter()
        .filter(|r| r.time.as_secs_f64() > 1.3)
        .collect();
    let touching = sweeping
        .iter()
        .filter(|r| r.in_contact && Vec3::from(r.rendered_force_n).norm() > 0.3)
        .count();
    let contact_fraction = touching as f64 / sweeping.len() as f64;
    assert!(
        contact_fraction > 0.7,
        "in contact with > 0.3 N for {:.0} % of the sweep",
        contact_fraction * 100.0
    );
    let xs: Vec<f64> = steady
        .iter()
        .filter(|r| r.in_contact)
        .map(|r| r.position_m[0])
        .collect();
    let slid =
        xs.iter().cloned().fold(f64::MIN, f64::max) - xs.iter().cloned().fold(f64::MAX, f64::min);
    assert!(slid > 0.1, "slid {:.1} mm across the relief", slid * 1e3);

    // No pop-through: the finger is never more than a few millimetres inside the relief it is
    // rendered with (distance to the face under it, along the face's normal; the vertical
    // penetration is bounded too), and wherever it is inside, the rendered force pushes it out.
    // Out of a height field is towards the user, -z. (A live update may raise the relief under the finger by several millimetres: the blend
    // then brings the force up over a few tens of milliseconds, with the finger inside.)
    let mut deepest_normal_m: f64 = 0.0;
    let mut deepest_vertical_m: f64 = 0.0;
    for r in &steady {
        let m = &vision.models[r.surface_version as usize];
        let [x, y, z] = r.position_m;
        let s = m.height_at(x, y).expect("finite position");
        let vertical = z - s.z_m;
        let along_normal = vertical * s.face_normal.z.abs();
        deepest_vertical_m = deepest_vertical_m.max(vertical);
        deepest_normal_m = deepest_normal_m.max(along_normal);
        if along_normal > 0.001 {
            let outward = -r.desired_force_n[2];
            assert!(
                outward > 0.0,
                "at t = {:.3} s the finger is {:.1} mm inside but the force {:?} N does not push it out",
                r.time.as_secs_f64(),
                along_normal * 1e3,
                r.desired_force_n
            );
        }
    }
    let normal_bound_m = 0.01;
    let vertical_bound_m = 0.02;
    assert!(
        deepest_normal_m < normal_bound_m,
        "the finger went {:.2} mm inside the relief (along the normal)",
        deepest_normal_m * 1e3
    );
    assert!(
        deepest_vertical_m < vertical_bound_m,
        "the finger went {:.2} mm below the relief",
        deepest_vertical_m * 1e3
    );

    // Swaps: in the period a new version is first rendered, the force changes by at most the
    // blend's bound over what the finger's own motion changed it by just before.
    let mut worst_swap_step: f64 = 0.0;
    let mut worst_swap_excess: f64 = f64::MIN;
    let mut swaps = 0;
    for (i, w) in records.windows(2).enumerate() {
        let (a, b) = (&w[0], &w[1]);
        if b.surface_version == a.surface_version || b.cycle != a.cycle + 1 {
            continue;
        }
        if b.force_scale < 1.0 || i < 6 {
            continue;
        }
        // A swap in the period the finger touches or leaves: the force steps by the damper's
        // B v_n switching at once whatever the model, which the bound on every period's step
        // below covers; the blend's bound is judged on swaps during contact or free motion.
        if a.in_contact != b.in_contact {
            continue;
        }
        swaps += 1;
        let step = force_step(a, b);
        let motion = records[i - 5..=i]
            .windows(2)
            .map(|w| force_step(&w[0], &w[1]))
            .fold(0.0, f64::max);
        worst_swap_step = worst_swap_step.max(step);
        worst_swap_excess = worst_swap_excess.max(step - motion);
    }
    let max_step_any = steady
        .windows(2)
        .filter(|w| w[1].cycle == w[0].cycle + 1)
        .map(|w| force_step(w[0], w[1]))
        .fold(0.0, f64::max);
    // Anywhere, a period's force step is the proxy's bounded move plus the finger's own motion
    // against the spring and the damper: K (max proxy step + finger speed x period) + B (the
    // finger's speed: the damper's force can appear or vanish at once), plus 0.1 N for shading.
    let b = config.control.damping_n_s_per_m;
    let proxy_step_m = proxy_params().max_offset_step_m;
    let worst_step_excess = steady
        .windows(2)
        .filter(|w| w[1].cycle == w[0].cycle + 1)
        .map(|w| {
            let finger_step_m = Vec3::from(w[1].velocity_m_s).norm() * period_s;
            // The damper's force B v_n switches on and off at once: when the finger touches or
            // leaves, and where the contact force would pull (it is clamped to zero).
            let finger_speed_m_s = Vec3::from(w[0].velocity_m_s)
                .norm()
                .max(Vec3::from(w[1].velocity_m_s).norm());
            force_step(w[0], w[1]) - k * (proxy_step_m + finger_step_m) - b * finger_speed_m_s
        })
        .fold(f64::NEG_INFINITY, f64::max);
    let mut times: Vec<f64> = vision
        .update_times
        .iter()
        .map(|d| d.as_secs_f64() * 1e3)
        .collect();
    times.sort_by(f64::total_cmp);
    eprintln!(
        "demo pair: {} matched 3D segments, {} used as constraints, initial build {:.2} ms; \
         {updates} live updates (median {:.1} ms, max {:.1} ms, debug build), {swaps} swaps rendered; \
         contact {:.0} % of the sweep, slid {:.0} mm; deepest {:.2} mm along the normal \
         (bound {:.0} mm), {:.2} mm vertically (bound {:.0} mm); \
         max force step at a swap {:.3} N (excess over motion {:.3} N, blend bound {:.3} N), \
         anywhere {:.3} N",
        initial.segments_3d,
        initial.report.constraints_kept,
        initial.build_time.as_secs_f64() * 1e3,
        times[times.len() / 2],
        times[times.len() - 1],
        contact_fraction * 100.0,
        slid * 1e3,
        deepest_normal_m * 1e3,
        normal_bound_m * 1e3,
        deepest_vertical_m * 1e3,
        vertical_bound_m * 1e3,
        worst_swap_step,
        worst_swap_excess,
        blend.max_step_n,
        max_step_any
    );
    assert!(swaps >= 20, "{swaps} swaps rendered");
    assert!(
        worst_swap_excess <= blend.max_step_n + 0.01,
        "a swap added {worst_swap_excess:.3} N to the force step (bound {:.3} N)",
        blend.max_step_n
    );
    assert!(
        worst_step_excess < 0.1,
        "a force step exceeded K (proxy step + finger step) + B (finger speed) by {worst_step_excess:.3} N (bound 0.1 N); largest step {max_step_any:.3} N"
    );
}
