//! Building the bas-relief from 300 matched segments (goal: under 2 ms) with the default
//! (the paper's interpolated surface) and the stepped shape, and the local update (merge a
//! region's fresh segments, rebuild).

use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;
use videt_relief::{build_from_scene, region::merge_region, ReliefShape};

#[path = "surface_scene/mod.rs"]
mod common;

fn bench_build(c: &mut Criterion) {
    let (params, cam) = common::setup();
    let segments = common::scene_segments(300, 1);
    let (model, report) = build_from_scene(&segments, &[], &cam, &params).unwrap();
    eprintln!(
        "300 segments: {} kept as constraints, {} rejected, {} crossings split; {:?}",
        report.constraints_kept,
        report.rejections.len(),
        report.crossings_split,
        model.stats()
    );
    c.bench_function("surface_build_300_segments", |b| {
        b.iter(|| build_from_scene(black_box(&segments), &[], &cam, &params).unwrap())
    });
    let mut stepped = params;
    stepped.shape = ReliefShape::Stepped;
    c.bench_function("surface_build_300_segments_stepped", |b| {
        b.iter(|| build_from_scene(black_box(&segments), &[], &cam, &stepped).unwrap())
    });
    let fresh = common::scene_segments(300, 2);
    c.bench_function("surface_local_update_100px_region_300_segments", |b| {
        b.iter(|| {
            let merged = merge_region(
                black_box(&segments),
                &fresh,
                &cam,
                [270.0, 190.0, 370.0, 290.0],
            );
            build_from_scene(&merged, &[], &cam, &params).unwrap()
        })
    });
}

criterion_group!(benches, bench_build);
criterion_main!(benches);
