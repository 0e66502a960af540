//! Why left segments stay unmatched, by category, on the Middlebury pairs of the shared data
//! (ground truth is used here only to find each unmatched segment's true partners).
//!
//! A right segment is a *partner* of a left segment when the left samples on the right
//! segment's rows, moved by their true disparity, land within 1.5 px of it (at least half of
//! them, over at least a third of the left segment's height); for nearly horizontal segments
//! the correspondence judge of `videt_evaluation` decides. Each unmatched left segment
//! is classified by its partner that got furthest through the matcher (a candidate before a
//! pair failing the photometric check before a pair failing a weak constraint), then by what
//! stopped that candidate.
//!
//! Segments without a partner are split by what lies near their true position in the right
//! image. `--list` prints every unmatched segment (with, for nearly horizontal ones, how each
//! partner fits the matched neighbours' contexts) and the wrong matches; `--completed` prints
//! the matches that completion added and how they fared; `key=value` overrides a few
//! completion parameters (see the source).
//!
//! The pair `map` is the synthetic printed map before a background plane
//! (`videt_evaluation::synthetic::printed_map_scene`); any other name is looked up among the extra
//! pairs of `scripts/fetch-extra-stereo.sh` (`target/extra-stereo/NAME`).
//!
//! `cargo run --release -p videt-evaluation --example unmatched_reasons [pair ...] [--list]
//! [--completed] [key=value ...]`

use std::collections::BTreeMap;
use videt_evaluation::{
    judge, judge_correspondence, load_middlebury_truth, point_segment_distance, DisparityMap,
    MatchVerdict, MIDDLEBURY_PAIRS,
};
use videt_vision::canny::CannyWorkspace;
use videt_vision::matching::{
    ImagePatch, MatchWorkspace, PairDiagnosis, SegmentMatch, StereoImages,
};
use videt_vision::segments::Segment;
use videt_vision::{run_pipeline, GrayView, VisionParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let list = args.iter().any(|a| a == "--list");
    let wanted: Vec<&str> = args
        .iter()
        .filter(|a| !a.starts_with("--") && !a.contains('='))
        .map(|a| a.as_str())
        .collect();
    let mut params = VisionParams::default();
    for arg in args.iter().filter(|a| a.contains('=')) {
        let (key, value) = arg.split_once('=').unwrap_or_default();
        let v: f32 = value.parse()?;
        let m = &mut params.matching;
        match key {
            "completion" => m.completion = v != 0.0,
            "completion_max_disparity_slope" => m.completion_max_disparity_slope = v,
            "completion_max_photometric_error" => m.completion_max_photometric_error = v,
            "completion_max_angle_diff_deg" => m.completion_max_angle_diff_deg = v,
            "completion_min_length_ratio" => m.completion_min_length_ratio = v,
            "completion_end_radius_px" => m.completion_end_radius_px = v,
            "completion_max_disparity_change_px" => m.completion_max_disparity_change_px = v,
            "completion_min_row_overlap_ratio" => m.completion_min_row_overlap_ratio = v,
            "completion_tolerance_px" => m.completion_tolerance_px = v,
            "completion_gradient_limit" => m.completion_gradient_limit = v,
            _ => return Err(format!("unknown parameter {key}").into()),
        }
    }
    let mut pairs = Vec::new();
    for (name, scale) in MIDDLEBURY_PAIRS {
        if !wanted.is_empty() && !wanted.contains(&name) {
            continue;
        }
        let Some(dir) = videt_testdata::data_dir(&format!("stereo/{name}")) else {
            continue;
        };
        pairs.push((
            name.to_string(),
            image::open(dir.join("left.ppm"))?.to_luma8(),
            image::open(dir.join("right.ppm"))?.to_luma8(),
            load_middlebury_truth(&dir, scale)?,
        ));
    }
    // Pairs of `scripts/fetch-extra-stereo.sh` (target/extra-stereo/NAME), by name.
    let extra = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/extra-stereo");
    for name in &wanted {
        let dir = extra.join(name);
        let Ok(scale) = std::fs::read_to_string(dir.join("scale.txt")) else {
            continue;
        };
        let p = videt_evaluation::load_truth_pair(&dir, name, scale.trim().parse()?, false)?;
        pairs.push((p.name, p.left, p.right, p.truth));
    }
    if wanted.contains(&"map") {
        let (w, h) = (640, 480);
        let (left, right, truth) = videt_evaluation::synthetic::printed_map_scene(w, h, 1);
        pairs.push((
            "map".to_string(),
            image::GrayImage::from_raw(w as u32, h as u32, left).ok_or("map size")?,
            image::GrayImage::from_raw(w as u32, h as u32, right).ok_or("map size")?,
            DisparityMap {
                width: w,
                height: h,
                values: truth,
            },
        ));
    }
    for (name, left_img, right_img, truth) in &pairs {
        let (lv, rv) = (
            GrayView::from_image(left_img)?,
            GrayView::from_image(right_img)?,
        );
        let out = run_pipeline(&lv, &rv, None, &params)?;
        // The matcher again, on the same segments and smoothed images, to inspect its state.
        let (mut cl, mut cr) = (CannyWorkspace::new(), CannyWorkspace::new());
        cl.detect(&lv, &params.canny)?;
        cr.detect(&rv, &params.canny)?;
        let images = StereoImages {
            left: patch(&cl),
            right: patch(&cr),
        };
        let mut ws = MatchWorkspace::new();
        let mut matches = Vec::new();
        let (ls, rs) = (&out.left_segments, &out.right_segments);
        ws.match_segments(ls, rs, Some(&images), &params.matching, &mut matches);
        assert_eq!(
            matches, out.matches,
            "the rerun must reproduce the pipeline"
        );
        if args.iter().any(|a| a == "--completed") {
            let mut plain = params.matching;
            plain.completion = false;
            let mut ws0 = MatchWorkspace::new();
            let mut before = Vec::new();
            ws0.match_segments(ls, rs, Some(&images), &plain, &mut before);
            for m in &matches {
                if before.iter().any(|b| b.left == m.left) {
                    continue;
                }
                let l = &ls[m.left as usize];
                let v = judge(l, &rs[m.right as usize], m, truth);
                let strict = ws0.diagnose_pair(ls, rs, Some(&images), &plain, m.left, m.right);
                let strict = match strict {
                    PairDiagnosis::Candidate(c) => format!(
                        "cand sup {} best {} cons {} free {} reached {}",
                        c.support, c.best_of_left, c.consistent, c.right_free, c.reached
                    ),
                    other => format!("{other:?}"),
                };
                println!(
                    "  new {v:?} {} len {:.0} ang {:.0} d [{:.1},{:.1}] truth {:?} agree {} horiz {} | {strict}",
                    pair_text(m, l),
                    l.length_px,
                    l.angle_rad.to_degrees(),
                    m.disparity_px[0],
                    m.disparity_px[1],
                    true_disparity(l, truth),
                    m.support,
                    m.nearly_horizontal
                );
            }
        }
        let mut matched = vec![false; ls.len()];
        for m in &matches {
            matched[m.left as usize] = true;
        }
        let horizontal = params.matching.horizontal_angle_deg.to_radians();
        let mut classes: BTreeMap<String, Vec<u32>> = BTreeMap::new();
        for (i, l) in ls.iter().enumerate() {
            if matched[i] {
                continue;
            }
            let h = l.is_nearly_horizontal(horizontal);
            let partners: Vec<u32> = (0..rs.len() as u32)
                .filter(|&j| is_partner(l, &rs[j as usize], h, truth))
                .collect();
            let kind = if h { "horiz" } else { "ordinary" };
            let class = if partners.is_empty() {
                if truth_known(l, truth) {
                    no_partner_kind(l, rs, truth).to_string()
                } else {
                    "no truth".to_string()
                }
            } else {
                let diagnoses: Vec<PairDiagnosis> = partners
                    .iter()
                    .map(|&j| {
                        ws.diagnose_pair(ls, rs, Some(&images), &params.matching, i as u32, j)
                    })
                    .collect();
                classify(&diagnoses, params.matching.min_support)
            };
            let key = format!("{kind:<8} {class}");
            if list {
                let d = true_disparity(l, truth);
                println!(
                    "  L{i} ({:.0},{:.0})-({:.0},{:.0}) len {:.0} ang {:.0} pol {} truth {:?} | {key} | partners {:?}",
                    l.start[0],
                    l.start[1],
                    l.end[0],
                    l.end[1],
                    l.length_px,
                    l.angle_rad.to_degrees(),
                    l.polarity,
                    d,
                    partners
                        .iter()
                        .map(|&j| (
                            j,
                            ws.diagnose_pair(ls, rs, Some(&images), &params.matching, i as u32, j)
                        ))
                        .collect::<Vec<_>>()
                );
            }
            if list && h {
                for &j in &partners {
                    for f in ws.diagnose_horizontal(ls, rs, i as u32, j) {
                        println!(
                            "      R{j} ({:.0},{:.0})-({:.0},{:.0}) context {:.1} line {:.1} end d {:.1},{:.1} overlap {:.2}",
                            rs[j as usize].start[0],
                            rs[j as usize].start[1],
                            rs[j as usize].end[0],
                            rs[j as usize].end[1],
                            f[0], f[1], f[2], f[3], f[4]
                        );
                    }
                }
            }
            classes.entry(key).or_default().push(i as u32);
        }
        let wrong: Vec<&SegmentMatch> = matches
            .iter()
            .filter(|m| {
                let l = &ls[m.left as usize];
                let v = judge(l, &rs[m.right as usize], m, truth);
                v == MatchVerdict::Wrong
            })
            .collect();
        println!(
            "{name}: {} left segments, {} matched, {} unmatched, {} wrong",
            ls.len(),
            matches.len(),
            ls.len() - matches.len(),
            wrong.len()
        );
        let mut sorted: Vec<_> = classes.into_iter().collect();
        sorted.sort_by(|a, b| b.1.len().cmp(&a.1.len()).then(a.0.cmp(&b.0)));
        for (key, members) in sorted {
            println!("  {:>4}  {key}", members.len());
        }
        if list {
            for m in wrong {
                let l = &ls[m.left as usize];
                println!(
                    "  wrong {} d {:?} truth {:?} support {} pred {} horiz {}",
                    pair_text(m, l),
                    m.disparity_px,
                    true_disparity(l, truth),
                    m.support,
                    m.predicted,
                    m.nearly_horizontal
                );
            }
        }
    }
    Ok(())
}

/// The category of an unmatched segment from the diagnoses of its partners.
fn classify(diagnoses: &[PairDiagnosis], min_support: u32) -> String {
    let candidate = diagnoses.iter().find_map(|d| match d {
        PairDiagnosis::Candidate(c) => Some(*c),
        _ => None,
    });
    if let Some(c) = candidate {
        return if c.horizontal {
            if !c.right_free {
                "cand: right taken".into()
            } else if !c.reached {
                "cand: no matched neighbour continuous".into()
            } else {
                "cand: shifted fit fails".into()
            }
        } else if c.support < min_support {
            "cand: no support".into()
        } else if !c.best_of_left {
            "cand: not best of its left segment".into()
        } else if !c.consistent {
            "cand: beaten on its right rows".into()
        } else if !c.right_free {
            "cand: right rows taken".into()
        } else if !c.reached {
            "cand: not reached (no continuous matched neighbour)".into()
        } else {
            "cand: reached but not accepted".into()
        };
    }
    if diagnoses
        .iter()
        .any(|d| matches!(d, PairDiagnosis::Photometric(_)))
    {
        return "photometric".into();
    }
    if diagnoses
        .iter()
        .any(|d| matches!(d, PairDiagnosis::Unlisted))
    {
        return "meets the constraints, not a candidate".into();
    }
    let mut names: Vec<String> = diagnoses
        .iter()
        .filter_map(|d| match d {
            PairDiagnosis::Constraint(c) => Some(format!("{c:?}")),
            _ => None,
        })
        .collect();
    names.sort();
    names.dedup();
    format!("constraint: {}", names.join("+"))
}

/// Whether `r` is a true partner of `l` (see the module documentation).
fn is_partner(l: &Segment, r: &Segment, horizontal: bool, truth: &DisparityMap) -> bool {
    if horizontal {
        l.polarity == r.polarity && judge_correspondence(l, r, truth) == MatchVerdict::Correct
    } else {
        videt_evaluation::partners::is_partner(l, r, truth)
    }
}

fn patch(c: &CannyWorkspace) -> ImagePatch<'_> {
    ImagePatch {
        data: c.smoothed(),
        width: c.width(),
        height: c.height(),
        origin_px: (0, 0),
    }
}

/// What lies near the true position of a left segment without a partner.
fn no_partner_kind(l: &Segment, rs: &[Segment], truth: &DisparityMap) -> &'static str {
    let mut best_same = 0usize;
    let mut best_opposite = 0usize;
    for r in rs {
        let n = landing_samples(l, r, truth);
        if r.polarity == l.polarity {
            best_same = best_same.max(n);
        } else {
            best_opposite = best_opposite.max(n);
        }
    }
    let steps = l.length_px.ceil().max(1.0) as usize + 1;
    if 3 * best_same >= steps {
        "no partner: same polarity, lands off-line or beyond rows"
    } else if best_same >= 3 {
        "no partner: same polarity piece covering < 1/3"
    } else if best_opposite >= 3 {
        "no partner: opposite polarity only"
    } else {
        "no partner: nothing near"
    }
}

/// Left samples that, moved by a true disparity, land within 1.5 px of `r` (any rows).
fn landing_samples(l: &Segment, r: &Segment, truth: &DisparityMap) -> usize {
    let steps = l.length_px.ceil().max(1.0) as usize;
    let mut landing = 0;
    for k in 0..=steps {
        let t = k as f32 / steps as f32;
        let x = l.start[0] + t * (l.end[0] - l.start[0]);
        let y = l.start[1] + t * (l.end[1] - l.start[1]);
        let (xi, yi) = (x.round() as i64, y.round() as i64);
        let mut lands = false;
        for dy in -2..=2 {
            for dx in -2..=2 {
                if let Some(d) = truth.at(xi + dx, yi + dy) {
                    lands |= point_segment_distance([x - d, y], r) <= 1.5;
                }
            }
        }
        landing += lands as usize;
    }
    landing
}

fn truth_known(l: &Segment, truth: &DisparityMap) -> bool {
    true_disparity(l, truth).is_some()
}

/// Median true disparity along the segment.
fn true_disparity(l: &Segment, truth: &DisparityMap) -> Option<f32> {
    let steps = l.length_px.ceil().max(1.0) as usize;
    let mut v: Vec<f32> = (0..=steps)
        .filter_map(|k| {
            let t = k as f32 / steps as f32;
            let x = l.start[0] + t * (l.end[0] - l.start[0]);
            let y = l.start[1] + t * (l.end[1] - l.start[1]);
            truth.at(x.round() as i64, y.round() as i64)
        })
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    Some(v[v.len() / 2])
}

/// `L<left> -> R<right> (x0,y0)-(x1,y1)`: a match and its left segment's endpoints.
fn pair_text(m: &SegmentMatch, l: &Segment) -> String {
    format!(
        "L{} -> R{} ({:.0},{:.0})-({:.0},{:.0})",
        m.left, m.right, l.start[0], l.start[1], l.end[0], l.end[1]
    )
}
