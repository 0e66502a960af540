//! The bas-relief of the demo stereo pair (Middlebury tsukuba, 384 x 288): the whole build at
//! start-up (stereo pipeline + surface build), and one live update around the finger (local
//! re-match of a 72 x 72 px region + merge + rebuild), the vision thread's work at 15 Hz.

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use videt_service::stereo_relief::{LiveSettings, StereoPair, StereoRelief};

fn bench_stereo_relief(c: &mut Criterion) {
    bench_variant(c, "", false);
    bench_variant(c, "_interpolated", true);
}

/// The benches with the defaults (the stepped relief with depth from patches every 12 px), or
/// with `paper` the paper's relief of the segments alone; named with `suffix`.
fn bench_variant(c: &mut Criterion, suffix: &str, paper: bool) {
    let mut config = videt_config::Config::default();
    if paper {
        config.vision.relief_shape = videt_config::ReliefShapeName::Interpolated;
        config.vision.patch_spacing_px = 0;
    }
    let layout = videt_runtime::setup::relief_layout(&config);
    let live = LiveSettings {
        patch_spacing_px: config.vision.patch_spacing_px,
        ..LiveSettings::default()
    };
    let pair = StereoPair::demo().unwrap();
    let (mut relief, _, initial) = StereoRelief::build(pair.clone(), &layout, live).unwrap();
    eprintln!(
        "demo pair{suffix}: {} matches, {} 3D segments, {} used as constraints, {} triangles",
        initial.matches,
        initial.segments_3d,
        initial.report.constraints_kept,
        initial.report.triangles
    );
    c.bench_function(
        &format!("stereo_relief_initial_build_demo_pair{suffix}"),
        |b| b.iter(|| StereoRelief::build(black_box(pair.clone()), &layout, live).unwrap()),
    );
    // The finger sweeping across the area, 2 mm between updates.
    let [cx, cy] = layout.centre_m;
    let positions: Vec<[f64; 3]> = (0..70)
        .map(|k| [cx - 0.07 + 0.002 * k as f64, cy + 0.03, 0.34])
        .collect();
    // Stage medians of a live update.
    let mut stages: [Vec<std::time::Duration>; 3] = Default::default();
    for p in &positions {
        let (_, u) = relief.update_around(*p, [0.03, 0.0, 0.0]).unwrap().unwrap();
        stages[0].push(u.match_time);
        stages[1].push(u.merge_time);
        stages[2].push(u.build_time);
    }
    let [matching, merge, build] = stages.map(|mut v| {
        v.sort_unstable();
        v[v.len() / 2]
    });
    eprintln!(
        "live update stage medians{suffix}: match {matching:?}, merge {merge:?}, rebuild {build:?}"
    );
    let mut k = 0;
    c.bench_function(
        &format!("stereo_relief_live_update_72px_region_demo_pair{suffix}"),
        |b| {
            b.iter(|| {
                k = (k + 1) % positions.len();
                relief
                    .update_around(black_box(positions[k]), [0.03, 0.0, 0.0])
                    .unwrap()
                    .unwrap()
            })
        },
    );
}

criterion_group!(benches, bench_stereo_relief);
criterion_main!(benches);
