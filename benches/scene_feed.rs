//! What the service's one feed type and its one hardware wrapper cost the control thread, in one
//! run: a period's surface (`current`, then the contact at the finger) through the relief feed
//! itself and through `SceneFeed` (the box relief, the finger sweeping across it), and through
//! the wall itself and through `SceneFeed`; the twin's tension readings raw and through
//! `CorrectedTensions` without and with a strain-gauge calibration.
//!
//! `cargo bench --bench scene_feed`

use criterion::measurement::WallTime;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use std::hint::black_box;
use videt_control::{Surface, Vec3};
use videt_hal::TensionSensors;
use videt_runtime::snapshot::{FixedSurface, SurfaceFeed};
use videt_service::init::corrected::CorrectedTensions;
use videt_service::relief_feed::relief_channel_for;
use videt_service::relief_scene::box_relief;
use videt_service::scene_feed::SceneFeed;

/// The finger's positions: across the box and off its edge, 1 mm apart.
fn sweep(centre: [f64; 2], z: f64) -> Vec<Vec3> {
    (0..160)
        .map(|k| Vec3::new(centre[0] - 0.08 + 0.001 * k as f64, centre[1], z))
        .collect()
}

/// One period's surface: the feed's current view, and the contact at `p`.
fn period<F: SurfaceFeed>(feed: &mut F, p: &Vec3) -> Option<f64> {
    let view = feed.current();
    view.surface.contact(p).map(|c| c.depth_m)
}

/// Bench `name`: one period of `feed` per iteration, the finger moving along `points`.
fn bench_periods<F: SurfaceFeed>(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    mut feed: F,
    points: &[Vec3],
) {
    let mut k = 0;
    group.bench_function(name, |b| {
        b.iter(|| {
            k = (k + 1) % points.len();
            black_box(period(&mut feed, black_box(&points[k])))
        })
    });
}

/// Bench `name`: one reading of `sensors`' fresh tensions per iteration.
fn bench_readings(
    group: &mut BenchmarkGroup<'_, WallTime>,
    name: &str,
    mut sensors: impl TensionSensors<3>,
) {
    let mut out = [0.0; 3];
    group.bench_function(name, |b| {
        b.iter(|| black_box(sensors.read_fresh_tensions(black_box(&mut out))).ok())
    });
}

fn bench_feeds(c: &mut Criterion) {
    let config = videt_config::Config::default();
    let layout = videt_runtime::setup::relief_layout(&config);
    let (model, _) = box_relief(&layout, 0.0).unwrap();
    let points = sweep(layout.centre_m, layout.back_plane_z_m - 0.02);
    let mut group = c.benchmark_group("scene_feed");
    let (_writer, direct) = relief_channel_for(&config, model.clone()).unwrap();
    bench_periods(&mut group, "relief_feed", direct, &points);
    let (_writer, relief) = relief_channel_for(&config, model).unwrap();
    let relief = SceneFeed::Relief(Box::new(relief));
    bench_periods(&mut group, "relief_in_scene_feed", relief, &points);
    let wall = videt_runtime::setup::check_wall();
    bench_periods(&mut group, "wall", FixedSurface(wall), &points);
    let wall = SceneFeed::Wall(FixedSurface(wall));
    bench_periods(&mut group, "wall_in_scene_feed", wall, &points);
    group.finish();
}

fn bench_tensions(c: &mut Criterion) {
    let config = videt_config::Config::default();
    let twin = || videt_assembly::twin_scene::wireman_wall_scene(&config, 1).twin;
    let mut group = c.benchmark_group("tension_readings");
    bench_readings(&mut group, "twin", twin());
    let passing = CorrectedTensions::new(twin(), None);
    bench_readings(&mut group, "corrected_without_calibration", passing);
    let calibration = videt_config::calibration::TensionCalibration::default();
    let corrected = CorrectedTensions::new(twin(), Some(calibration));
    bench_readings(&mut group, "corrected", corrected);
    group.finish();
}

criterion_group!(benches, bench_feeds, bench_tensions);
criterion_main!(benches);
