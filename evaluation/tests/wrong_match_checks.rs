//! The checks against wrong matches on the scene they are for: a repeated pattern (a brick
//! wall, procedural, so the test needs no data), where a left edge finds a neighbouring
//! brick's edge as plausible as its own. Without a check the matcher makes many wrong matches
//! there (11.5 %); the left-right check removes most of them (0 %), the confidence threshold
//! some (8 %).

use std::sync::Arc;

use videt_evaluation::synthetic::{plane_axes, render_rig, Imaging, Lcg, Panel, Rig, Texture};
use videt_evaluation::{evaluate, DisparityMap};
use videt_vision::matching::MatchChecks;
use videt_vision::{GrayView, StereoPipeline, VisionParams};

const WIDTH: usize = 320;
const HEIGHT: usize = 240;

/// Bricks 40 x 16 texels in staggered courses, nearly alike (grey 140..152), mortar 2 texels wide, a
/// little texel noise.
fn bricks(seed: u64) -> Texture {
    let (w, h) = (320, 256);
    let mut rng = Lcg::new(seed);
    let greys: Vec<u8> = (0..400).map(|_| 140 + rng.below(12) as u8).collect();
    let mut texels = vec![0u8; w * h];
    for y in 0..h {
        let course = y / 16;
        let shift = if course % 2 == 0 { 0 } else { 20 };
        for x in 0..w {
            let brick = (x + shift) / 40;
            let mortar = y % 16 < 2 || (x + shift) % 40 < 2;
            let noise = rng.below(9) as i32 - 4;
            let base = if mortar {
                60
            } else {
                i32::from(greys[(course * 9 + brick) % greys.len()])
            };
            texels[y * w + x] = (base + noise).clamp(0, 255) as u8;
        }
    }
    Texture::from_gray(w, h, &texels)
}

/// A brick wall turned 20 degrees, filling the view at about 1.2 m.
fn scene() -> (Vec<u8>, Vec<u8>, DisparityMap) {
    let rig = Rig {
        supersampling: 2,
        ..Rig::new(WIDTH, HEIGHT, 270.0, 0.06)
    };
    let mut wall = Panel::new(
        [0.03, 0.0, 1.2],
        [3.0, 2.0],
        plane_axes(20.0, 0.0, 0.0),
        Arc::new(bricks(7)),
    );
    wall.repeat = [5.0, 2.0];
    let camera = |seed, gain, offset| Imaging {
        blur_sigma_px: 0.7,
        vignetting: 0.1,
        gain,
        offset,
        noise_sigma: 2.0,
        seed,
    };
    let pair = render_rig(
        &rig,
        &[wall],
        [&camera(1, 1.0, 0.0), &camera(2, 1.05, -4.0)],
    );
    let truth = DisparityMap {
        width: WIDTH,
        height: HEIGHT,
        values: pair.disparity_left,
    };
    (pair.left, pair.right, truth)
}

/// Non-horizontal matches and the fraction of them wrong, with `checks`.
fn run(left: &[u8], right: &[u8], truth: &DisparityMap, checks: MatchChecks) -> (usize, f64) {
    let mut params = VisionParams::default();
    checks.apply(&mut params.matching);
    let lv = GrayView::new(left, WIDTH, HEIGHT).unwrap();
    let rv = GrayView::new(right, WIDTH, HEIGHT).unwrap();
    let out = StereoPipeline::new()
        .run(&lv, &rv, None, &params)
        .unwrap()
        .clone();
    let r = evaluate(&out.left_segments, &out.right_segments, &out.matches, truth);
    (
        r.matches - r.horizontal_matches,
        r.wrong_fraction_not_horizontal(),
    )
}

#[test]
fn on_a_brick_wall_the_checks_remove_wrong_matches() {
    let (left, right, truth) = scene();
    let (n0, without) = run(&left, &right, &truth, MatchChecks::NONE);
    let left_right = MatchChecks {
        left_right: true,
        ..MatchChecks::NONE
    };
    let confidence = MatchChecks {
        min_confidence: 0.2,
        ..MatchChecks::NONE
    };
    let (n1, with_lr) = run(&left, &right, &truth, left_right);
    let (n2, with_confidence) = run(&left, &right, &truth, confidence);
    eprintln!(
        "brick wall: no check {n0} matches, {:.1} % wrong; left-right {n1}, {:.1} %; confidence 0.2 {n2}, {:.1} %",
        100.0 * without,
        100.0 * with_lr,
        100.0 * with_confidence
    );
    assert!(n0 >= 50, "the wall must be matched at all: {n0} matches");
    assert!(
        without >= 0.05,
        "the pattern must fool the matcher: {without}"
    );
    assert!(
        with_lr <= 0.5 * without,
        "left-right: {with_lr} vs {without}"
    );
    assert!(
        with_confidence < without,
        "confidence: {with_confidence} vs {without}"
    );
    assert!(n1 * 2 >= n0 && n2 * 2 >= n0, "the checks keep most matches");
}
