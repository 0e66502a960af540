//! Matching accuracy that cannot flatter itself: the parameters are chosen on some pairs and
//! the figures reported on another, for the matcher alone and with each check against wrong
//! matches (`MatchParams::mutual_check`, `min_confidence`, `surface_check`) alone and combined.
//!
//! - The shared Middlebury pairs (tsukuba, venus, cones, teddy), leave-one-out: for each, the
//!   parameters are chosen on the other three, then the pair is run with them.
//! - Extra pairs (`scripts/fetch-extra-stereo.sh`: Middlebury 2014 Motorcycle and scenes
//!   synthesised from photographs), which nothing was ever tuned on: run with the parameters
//!   chosen on all four shared pairs, and with the defaults.
//! - The defaults, for reference: they were chosen on the four shared pairs, so on those they
//!   are in-sample figures (marked so).
//!
//! The disparity bound of every run is measured on its pair as `videt vision` does when
//! `--max-disparity` is not given (`videt_vision::disparity_range`), once per pair and base
//! setting, with the checks off.
//!
//! The headline is the wrong fraction among the matches that are not nearly horizontal (the
//! ones back-projected to 3D); "matched" is the fraction of those left segments matched;
//! "ceiling" is the fraction of them that have a partner in the right image at all (the most
//! any matcher of those segments could match, `videt_evaluation::partners`).
//! Choice on a training set, within one family of checks: among the family's settings that
//! match >= 60 % on every training pair (when none does: >= 60 % on average over them; when
//! none does either: all of them), the lowest mean wrong fraction, then the highest mean
//! matched fraction. A family's settings: the base grid (240 settings: Canny high threshold x
//! photometric limit x propagation angle x the photometric test's form, at the exact
//! disparity or sampling-insensitive "BT" x the right image's edge thresholds relative to the
//! left's) times the family's checks (the confidence threshold is one more grid axis where the
//! family has it). `--families a,b` keeps only the named families ("all three" among them).
//!
//! Two blocks: the checks around the defaults (the matcher's own parameters fixed at the
//! defaults', only the confidence threshold chosen), then each family with the matcher's
//! parameters chosen too.
//!
//! Trade-off curves (`--csv FILE`, `--figure FILE.png`): on each pair, all three checks around
//! the defaults, the confidence threshold swept from 0 to 0.6 (the one chosen without the
//! pair marked): wrong against matched.
//!
//! `cargo run --release -p videt-evaluation --example stereo_heldout [-- --extra DIR] [--grid]
//! [--csv FILE] [--figure FILE.png]` (DIR defaults to `target/extra-stereo`; pairs missing
//! there are skipped with a note).

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::FontStyle;
use videt_evaluation::partners::partnered;
use videt_evaluation::{evaluate, load_extra_pairs, load_truth_pair, TruthPair, MIDDLEBURY_PAIRS};
use videt_vision::disparity_range::choose_max_disparity;
use videt_vision::matching::MatchChecks;
use videt_vision::{GrayView, StereoPipeline, VisionParams};

/// Goal: at least this fraction of the non-horizontal left segments matched ...
const GOAL_MATCHED: f64 = 0.60;
/// ... and at most this fraction of those matches wrong.
const GOAL_WRONG: f64 = 0.02;

const CANNY_HIGH: [u16; 5] = [40, 50, 60, 80, 110];
const PHOTOMETRIC: [f32; 4] = [4.0, 5.0, 7.0, 10.0];
const PROPAGATE_ANGLE_DEG: [f32; 3] = [9.0, 13.0, 18.0];
const SAMPLING_INSENSITIVE: [bool; 2] = [false, true];
/// The right image's edge thresholds relative to the left's (`VisionParams::right_threshold_ratio`).
const RIGHT_THRESHOLD_RATIO: [f32; 2] = [1.0, 0.7];
/// Confidence thresholds of the families that have the confidence check.
const CONFIDENCE: [f32; 4] = [0.1, 0.15, 0.2, 0.3];
/// The trade-off curves' thresholds.
const SWEEP: [f32; 13] = [
    0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.45, 0.5, 0.55, 0.6,
];

/// One base setting (the matcher's own parameters).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Base {
    canny_high: u16,
    photometric: f32,
    propagate_angle_deg: f32,
    sampling_insensitive: bool,
    right_ratio: f32,
}

impl Base {
    fn params(&self) -> VisionParams {
        let mut p = VisionParams::default();
        p.canny.high_threshold = self.canny_high;
        p.canny.low_threshold = p.canny.low_threshold.min(self.canny_high);
        p.matching.max_photometric_error = self.photometric;
        p.matching.propagate_max_angle_diff_deg = self.propagate_angle_deg;
        p.matching.photometric_sampling_insensitive = self.sampling_insensitive;
        p.right_threshold_ratio = self.right_ratio;
        MatchChecks::NONE.apply(&mut p.matching);
        p
    }

    fn describe(&self) -> String {
        format!(
            "canny {:>3}{}, photo {:>4.1}{}, angle {:>4.1}",
            self.canny_high,
            if self.right_ratio < 1.0 {
                format!(" (right x{:.1})", self.right_ratio)
            } else {
                String::new()
            },
            self.photometric,
            if self.sampling_insensitive { " BT" } else { "" },
            self.propagate_angle_deg
        )
    }
}

/// A family of checks: its name and its settings of the checks.
fn families() -> Vec<(&'static str, Vec<MatchChecks>)> {
    let with = |left_right, surface, confidence: bool| -> Vec<MatchChecks> {
        let thresholds: &[f32] = if confidence { &CONFIDENCE } else { &[0.0] };
        thresholds
            .iter()
            .map(|&min_confidence| MatchChecks {
                left_right,
                min_confidence,
                surface,
            })
            .collect()
    };
    vec![
        ("none", with(false, false, false)),
        ("left-right", with(true, false, false)),
        ("confidence", with(false, false, true)),
        ("surface", with(false, true, false)),
        ("left-right + confidence", with(true, false, true)),
        ("left-right + surface", with(true, true, false)),
        ("confidence + surface", with(false, true, true)),
        ("all three", with(true, true, true)),
    ]
}

fn bases() -> Vec<Base> {
    let mut g = Vec::new();
    for canny_high in CANNY_HIGH {
        for photometric in PHOTOMETRIC {
            for propagate_angle_deg in PROPAGATE_ANGLE_DEG {
                for sampling_insensitive in SAMPLING_INSENSITIVE {
                    for right_ratio in RIGHT_THRESHOLD_RATIO {
                        g.push(Base {
                            canny_high,
                            photometric,
                            propagate_angle_deg,
                            sampling_insensitive,
                            right_ratio,
                        });
                    }
                }
            }
        }
    }
    g
}

/// The figures of one run.
#[derive(Debug, Clone, Copy, Default)]
struct Score {
    /// Non-horizontal left segments matched / non-horizontal left segments.
    matched: f64,
    /// Wrong / evaluated among non-horizontal matches.
    wrong: f64,
    /// Non-horizontal matches.
    matches: usize,
}

impl Score {
    fn meets_goal(&self) -> bool {
        self.matched >= GOAL_MATCHED && self.wrong <= GOAL_WRONG
    }
}

fn views(pair: &TruthPair) -> (GrayView<'_>, GrayView<'_>) {
    (
        GrayView::from_image(&pair.left).expect("left view"),
        GrayView::from_image(&pair.right).expect("right view"),
    )
}

/// The disparity bound measured on the pair, as `videt vision` does by default.
fn bound(pipeline: &mut StereoPipeline, pair: &TruthPair, params: &VisionParams) -> f32 {
    let (lv, rv) = views(pair);
    choose_max_disparity(pipeline, &lv, &rv, params)
        .expect("disparity range")
        .max_px
}

fn score(pipeline: &mut StereoPipeline, pair: &TruthPair, params: &VisionParams) -> Score {
    let (lv, rv) = views(pair);
    let out = pipeline.run(&lv, &rv, None, params).expect("pipeline");
    let r = evaluate(
        &out.left_segments,
        &out.right_segments,
        &out.matches,
        &pair.truth,
    );
    let horizontal = params.matching.horizontal_angle_deg.to_radians();
    let left_other = out
        .left_segments
        .iter()
        .filter(|s| !s.is_nearly_horizontal(horizontal))
        .count();
    let matched_other = r.matches - r.horizontal_matches;
    Score {
        matched: matched_other as f64 / left_other.max(1) as f64,
        wrong: r.wrong_fraction_not_horizontal(),
        matches: matched_other,
    }
}

/// The most a matcher of this run's segments could match: the fraction of the non-horizontal
/// left segments with a partner in the right image
/// (`videt_evaluation::partners`).
fn ceiling(pipeline: &mut StereoPipeline, pair: &TruthPair, params: &VisionParams) -> f64 {
    let (lv, rv) = views(pair);
    let out = pipeline.run(&lv, &rv, None, params).expect("pipeline");
    let (with, total) = partnered(
        &out.left_segments,
        &out.right_segments,
        &pair.truth,
        params.matching.horizontal_angle_deg.to_radians(),
    );
    with as f64 / total.max(1) as f64
}

/// Every setting: (base index, checks).
type Setting = (usize, MatchChecks);

/// The setting chosen among `settings` on the pairs `training` (`scores[setting][pair]`).
fn choose(settings: &[usize], scores: &[Vec<Score>], training: &[usize]) -> usize {
    let mean = |s: usize, f: fn(&Score) -> f64| {
        training.iter().map(|&p| f(&scores[s][p])).sum::<f64>() / training.len().max(1) as f64
    };
    let every: Vec<usize> = settings
        .iter()
        .copied()
        .filter(|&s| {
            training
                .iter()
                .all(|&p| scores[s][p].matched >= GOAL_MATCHED)
        })
        .collect();
    let on_average: Vec<usize> = settings
        .iter()
        .copied()
        .filter(|&s| mean(s, |s| s.matched) >= GOAL_MATCHED)
        .collect();
    let candidates = if !every.is_empty() {
        every
    } else if !on_average.is_empty() {
        on_average
    } else {
        settings.to_vec()
    };
    candidates
        .into_iter()
        .min_by(|&a, &b| {
            mean(a, |s| s.wrong)
                .total_cmp(&mean(b, |s| s.wrong))
                .then(mean(b, |s| s.matched).total_cmp(&mean(a, |s| s.matched)))
        })
        .expect("a non-empty family")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Runs `job(pair index)` for every pair on two threads (the pairs are independent).
fn per_pair<T: Send>(pairs: &[TruthPair], job: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<Option<T>> = (0..pairs.len()).map(|_| None).collect();
    let done: Vec<(usize, T)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if i >= pairs.len() {
                            break mine;
                        }
                        mine.push((i, job(i)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a worker"))
            .collect()
    });
    for (i, r) in done {
        results[i] = Some(r);
    }
    results
        .into_iter()
        .map(|r| r.expect("every pair"))
        .collect()
}

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

/// One pair's trade-off curve: its name, (threshold, score) points, the threshold chosen
/// without the pair, and whether it is a shared pair (left out of the choice) or an extra one
/// (never tuned on).
type Curve = (String, Vec<(f32, Score)>, f32, bool);

/// The trade-off curves, one panel per pair: wrong % against matched %, the chosen threshold
/// marked, the goal's corner shaded.
fn draw_tradeoff(path: &Path, curves: &[Curve]) -> Result<(), Box<dyn std::error::Error>> {
    register_font();
    let cols = 3usize;
    let rows = curves.len().div_ceil(cols).max(1);
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (1200, 360 * rows as u32)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((rows, cols));
        for ((name, curve, chosen, shared), area) in curves.iter().zip(&panels) {
            let max_wrong = curve
                .iter()
                .map(|(_, s)| 100.0 * s.wrong)
                .fold(4.0f64, f64::max)
                .min(12.0);
            let mut chart = ChartBuilder::on(area)
                .caption(
                    format!(
                        "{name} ({})",
                        if *shared {
                            "left out of the choice"
                        } else {
                            "never tuned on"
                        }
                    ),
                    ("sans-serif", 18),
                )
                .margin(10)
                .x_label_area_size(36)
                .y_label_area_size(44)
                .build_cartesian_2d(0.0f64..100.0, 0.0f64..max_wrong)?;
            chart
                .configure_mesh()
                .x_labels(6)
                .y_labels(5)
                .light_line_style(WHITE)
                .x_desc("matched %")
                .y_desc("wrong %")
                .label_style(("sans-serif", 13))
                .draw()?;
            chart.draw_series(std::iter::once(Rectangle::new(
                [(100.0 * GOAL_MATCHED, 0.0), (100.0, 100.0 * GOAL_WRONG)],
                RGBColor(200, 235, 200).filled(),
            )))?;
            chart.draw_series(LineSeries::new(
                curve
                    .iter()
                    .map(|(_, s)| (100.0 * s.matched, 100.0 * s.wrong)),
                &BLUE,
            ))?;
            chart.draw_series(curve.iter().map(|(t, s)| {
                let at = (100.0 * s.matched, 100.0 * s.wrong);
                if (t - chosen).abs() < 1e-6 {
                    Circle::new(at, 6, RED.filled())
                } else {
                    Circle::new(at, 3, BLUE.filled())
                }
            }))?;
            if let (Some(first), Some(last)) = (curve.first(), curve.last()) {
                for (t, s) in [first, last] {
                    chart.draw_series(std::iter::once(Text::new(
                        format!("{t:.2}"),
                        (100.0 * s.matched + 1.0, 100.0 * s.wrong + 0.1),
                        ("sans-serif", 12),
                    )))?;
                }
            }
        }
        root.present()?;
    }
    std::fs::rename(&tmp, path)?;
    Ok(())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value_of = |flag: &str| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map(PathBuf::from)
    };
    let extra_dir = value_of("--extra").unwrap_or_else(|| {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("..")
            .join("target/extra-stereo")
    });
    let mut pairs = Vec::new();
    for (name, scale) in MIDDLEBURY_PAIRS {
        match videt_testdata::data_dir(&format!("stereo/{name}")) {
            Some(dir) => pairs.push(load_truth_pair(&dir, name, scale, true)?),
            None => println!("{name}: not in the shared data, skipped"),
        }
    }
    pairs.extend(load_extra_pairs(&extra_dir)?);
    if !pairs.iter().any(|p| !p.shared) {
        println!(
            "no extra pairs in {} (run scripts/fetch-extra-stereo.sh): only leave-one-out",
            extra_dir.display()
        );
    }
    if pairs.iter().filter(|p| p.shared).count() < 2 {
        return Err("leave-one-out needs at least two shared pairs".into());
    }

    let bases = bases();
    let mut families = families();
    if let Some(only) = args
        .iter()
        .position(|a| a == "--families")
        .and_then(|i| args.get(i + 1))
    {
        let wanted: Vec<&str> = only.split(',').map(str::trim).collect();
        families.retain(|(name, _)| wanted.contains(name));
        if !families.iter().any(|(name, _)| *name == "all three") {
            return Err("--families must include \"all three\" (the trade-off curves)".into());
        }
    }
    let mut settings: Vec<Setting> = Vec::new();
    let mut family_settings: Vec<Vec<usize>> = Vec::new();
    for (_, checks) in &families {
        let mut mine = Vec::new();
        for b in 0..bases.len() {
            for c in checks {
                let s = (b, *c);
                let at = match settings.iter().position(|x| *x == s) {
                    Some(at) => at,
                    None => {
                        settings.push(s);
                        settings.len() - 1
                    }
                };
                mine.push(at);
            }
        }
        family_settings.push(mine);
    }
    let params_of = |(b, c): &Setting, bound_px: f32| {
        let mut p = bases[*b].params();
        c.apply(&mut p.matching);
        p.matching.disparity_max_px = bound_px;
        p
    };
    // scores_by_pair[pair][setting], the bound measured once per pair and base.
    let scores_by_pair: Vec<(Vec<f32>, Vec<Score>)> = per_pair(&pairs, |i| {
        let mut pipeline = StereoPipeline::new();
        let bounds: Vec<f32> = bases
            .iter()
            .map(|b| bound(&mut pipeline, &pairs[i], &b.params()))
            .collect();
        let scores = settings
            .iter()
            .map(|s| score(&mut pipeline, &pairs[i], &params_of(s, bounds[s.0])))
            .collect();
        (bounds, scores)
    });
    let scores: Vec<Vec<Score>> = (0..settings.len())
        .map(|s| scores_by_pair.iter().map(|(_, sc)| sc[s]).collect())
        .collect();
    let defaults: Vec<Score> = per_pair(&pairs, |i| {
        let mut pipeline = StereoPipeline::new();
        let mut p = VisionParams::default();
        p.matching.disparity_max_px = bound(&mut pipeline, &pairs[i], &p);
        score(&mut pipeline, &pairs[i], &p)
    });

    println!(
        "non-horizontal matches; goal >= {:.0} % matched and <= {:.0} % wrong on every pair",
        100.0 * GOAL_MATCHED,
        100.0 * GOAL_WRONG
    );
    let shared: Vec<usize> = (0..pairs.len()).filter(|&i| pairs[i].shared).collect();
    let training_of =
        |i: usize| -> Vec<usize> { shared.iter().copied().filter(|&j| j != i).collect() };
    // The defaults' own base setting (their checks aside).
    let default_base = {
        let mut d = VisionParams::default();
        MatchChecks::NONE.apply(&mut d.matching);
        bases
            .iter()
            .position(|b| b.params() == d)
            .ok_or("the defaults' base setting is not in the grid")?
    };
    let mut ceiling_pipeline = StereoPipeline::new();
    let mut summaries = Vec::new();
    let mut chosen_all_three = Vec::new();
    for (block, restricted) in [
        (
            "checks around the defaults (the matcher's own parameters fixed at the defaults'; \
             only the confidence threshold chosen without the pair)",
            true,
        ),
        (
            "the matcher's parameters chosen with each family of checks, without the pair",
            false,
        ),
    ] {
        println!("\n#### {block}");
        let mut summary = Vec::new();
        for ((family, _), mine) in families.iter().zip(&family_settings) {
            let mine: Vec<usize> = mine
                .iter()
                .copied()
                .filter(|&s| !restricted || settings[s].0 == default_base)
                .collect();
            println!(
                "\n== {family}\n{:<11} {:<66} {:>7} {:>8} {:>7} {:>8}  goal",
                "pair",
                "setting (chosen without the pair)",
                "matches",
                "matched",
                "wrong",
                "ceiling"
            );
            let mut held_out = Vec::new();
            for (i, pair) in pairs.iter().enumerate() {
                let chosen = choose(&mine, &scores, &training_of(i));
                let s = scores[chosen][i];
                held_out.push(s);
                if restricted && *family == "all three" {
                    chosen_all_three.push(chosen);
                }
                let (b, c) = settings[chosen];
                let top = ceiling(
                    &mut ceiling_pipeline,
                    pair,
                    &params_of(&settings[chosen], scores_by_pair[i].0[b]),
                );
                println!(
                    "{:<11} {:<66} {:>7} {:>7.1}% {:>6.2}% {:>7.1}%  {}",
                    pair.name,
                    format!("{}; {}", bases[b].describe(), c),
                    s.matches,
                    100.0 * s.matched,
                    100.0 * s.wrong,
                    100.0 * top,
                    if s.meets_goal() { "met" } else { "not" },
                );
            }
            let line = format!(
                "{:<24} wrong median {:5.2} %, worst {:5.2} %; matched median {:5.1} %, worst {:5.1} %; goal met on {} of {}",
                family,
                100.0 * median(held_out.iter().map(|s| s.wrong).collect()),
                100.0 * held_out.iter().map(|s| s.wrong).fold(0.0, f64::max),
                100.0 * median(held_out.iter().map(|s| s.matched).collect()),
                100.0 * held_out.iter().map(|s| s.matched).fold(1.0, f64::min),
                held_out.iter().filter(|s| s.meets_goal()).count(),
                held_out.len()
            );
            println!("{line}");
            summary.push(line);
        }
        let every: Vec<usize> = (0..settings.len())
            .filter(|&s| !restricted || settings[s].0 == default_base)
            .collect();
        let (b, c) = settings[choose(&every, &scores, &shared)];
        summary.push(format!(
            "chosen on all the shared pairs, over every family: {}; {}",
            bases[b].describe(),
            c
        ));
        summaries.push((block, summary));
    }
    println!(
        "\n== defaults (their checks: {})",
        MatchChecks::of(&VisionParams::default().matching)
    );
    for (pair, s) in pairs.iter().zip(&defaults) {
        println!(
            "{:<11} {:>7} {:>7.1}% {:>6.2}%  {:<4} {}",
            pair.name,
            s.matches,
            100.0 * s.matched,
            100.0 * s.wrong,
            if s.meets_goal() { "met" } else { "not" },
            if pair.shared {
                "in-sample (the defaults were chosen on the shared pairs)"
            } else {
                "held out (never tuned on)"
            }
        );
    }
    for (block, summary) in &summaries {
        println!("\n== held out, per family: {block}\n{}", summary.join("\n"));
    }

    // Trade-off curves: the "all three" family around the defaults, chosen without the pair,
    // its threshold swept.
    let curves: Vec<Curve> = per_pair(&pairs, |i| {
        let (b, c) = settings[chosen_all_three[i]];
        let bound_px = scores_by_pair[i].0[b];
        let mut pipeline = StereoPipeline::new();
        let curve = SWEEP
            .iter()
            .map(|&t| {
                let s = (
                    b,
                    MatchChecks {
                        min_confidence: t,
                        ..c
                    },
                );
                (t, score(&mut pipeline, &pairs[i], &params_of(&s, bound_px)))
            })
            .collect();
        (
            pairs[i].name.clone(),
            curve,
            c.min_confidence,
            pairs[i].shared,
        )
    });
    if let Some(path) = value_of("--csv") {
        let mut text = String::from("pair,held_out_by,threshold,matched,wrong,matches\n");
        for (name, curve, _, shared) in &curves {
            for (t, s) in curve {
                text.push_str(&format!(
                    "{name},{},{t:.2},{:.4},{:.4},{}\n",
                    if *shared {
                        "leave-one-out"
                    } else {
                        "never-tuned"
                    },
                    s.matched,
                    s.wrong,
                    s.matches
                ));
            }
        }
        let tmp = path.with_extension("tmp");
        std::fs::write(&tmp, text)?;
        std::fs::rename(&tmp, &path)?;
        println!("\ntrade-off curves written to {}", path.display());
    }
    if let Some(path) = value_of("--figure") {
        draw_tradeoff(&path, &curves)?;
        println!("trade-off figure written to {}", path.display());
    }
    if args.iter().any(|a| a == "--grid") {
        println!("\nevery setting (matched % / wrong %):");
        for (s, row) in settings.iter().zip(&scores) {
            let cells: Vec<String> = row
                .iter()
                .map(|c| format!("{:5.1}/{:4.2}", 100.0 * c.matched, 100.0 * c.wrong))
                .collect();
            println!(
                "  {:<52} {}",
                format!("{}; {}", bases[s.0].describe(), s.1),
                cells.join("  ")
            );
        }
    }
    Ok(())
}
