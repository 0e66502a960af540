//! Stage times of a surface build from 300 synthetic matched segments: the mean build and the
//! fastest run of each stage over 200 builds (quick look; the criterion bench `surface_build` is
//! the reference figure). `cargo bench -p videt-relief --bench surface_build_stages`

#[path = "surface_scene/mod.rs"]
mod common;

fn main() {
    let (params, cam) = common::setup();
    let segments = common::scene_segments(300, 1);
    let mut best = None::<videt_relief::BuildTimings>;
    let t = std::time::Instant::now();
    let runs = 200;
    for _ in 0..runs {
        let (_, report) = videt_relief::build_from_scene(&segments, &[], &cam, &params).unwrap();
        let r = report.timings;
        best = Some(match best {
            None => r,
            Some(b) => videt_relief::BuildTimings {
                cleaning: b.cleaning.min(r.cleaning),
                crossings: b.crossings.min(r.crossings),
                triangulation: b.triangulation.min(r.triangulation),
                model: b.model.min(r.model),
            },
        });
    }
    println!(
        "mean build {:?}; fastest stages {:?}",
        t.elapsed() / runs,
        best.unwrap()
    );
}
