//! `videt log LOG --plot DIR`: the figures of a session — the thimble's path with the desired
//! and rendered forces along it (the paper's Figs 18, 22, 23), tensions against set-points per
//! wire with the tension limits, desired against rendered force with the index V, the wake-up
//! latency and compute time histograms, and the safety events on the time axis.

use std::path::{Path, PathBuf};

use plotters::prelude::*;
use videt_control::safety::SafetyState;

use crate::plot_data::{norm, DrawnPeriod, Marks, SessionFigureData};
use crate::plotting::{
    draw_legend, line_mark, register_font, write_error as e, PlotError, TimeChart,
};
use videt_runtime::histogram::Histogram;
use videt_runtime::telemetry::RecordedSurface;

const WIRE_COLOURS: [RGBColor; 3] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
];
const GREY: RGBColor = RGBColor(127, 127, 127);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const BROWN: RGBColor = RGBColor(140, 86, 75);

/// The tension limits drawn on the tension plots, newtons.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionLimits {
    /// Minimum tension.
    pub t_min_n: f64,
    /// Maximum tension.
    pub t_max_n: f64,
}

/// Draw every figure of a session (`data`, gathered as its log was read; `surface`: the
/// surface most of its periods rendered, with its version, when the log recorded it) into
/// `dir`; returns the files written.
pub fn write_all(
    dir: &Path,
    data: &SessionFigureData,
    surface: Option<(u64, &RecordedSurface)>,
    limits: TensionLimits,
) -> Result<Vec<PathBuf>, PlotError> {
    let (Some(t0), records) = (data.safety.t0_s, data.drawn_periods()) else {
        return Err("the log has no records to plot".into());
    };
    register_font();
    std::fs::create_dir_all(dir).map_err(e(dir))?;
    let events = &data.safety.transitions;
    let mut written = Vec::new();
    let path = dir.join("path.png");
    path_plot(&path, &records, &data.first_contacts, surface)?;
    written.push(path);
    let path = dir.join("tensions.png");
    tensions_plot(&path, &records, t0, limits, events)?;
    written.push(path);
    let path = dir.join("forces.png");
    forces_plot(&path, &records, t0, events)?;
    written.push(path);
    let path = dir.join("timing.png");
    timing_plot(&path, [&data.wake, &data.compute])?;
    written.push(path);
    Ok(written)
}

/// The surface's section by the plane `y = y_m`, as (x, z) in metres, at `xs`.
fn surface_section(surface: &RecordedSurface, y_m: f64, xs: &[f64]) -> Vec<(f64, f64)> {
    match surface {
        RecordedSurface::Plane(p) => {
            let (n, q) = (p.normal(), p.point_m());
            if n.z.abs() < 1e-9 {
                return Vec::new();
            }
            xs.iter()
                .map(|&x| (x, q.z - (n.x * (x - q.x) + n.y * (y_m - q.y)) / n.z))
                .collect()
        }
        RecordedSurface::Relief(m) => xs
            .iter()
            .filter_map(|&x| m.height_at(x, y_m).map(|h| (x, h.z_m)))
            .collect(),
    }
}

/// Range of `values` with a margin (never empty).
fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let margin = ((hi - lo) * 0.08).max(1e-3);
    (lo - margin, hi + margin)
}

/// The path in the x-z plane (the profile's plane: the operator slides along x, presses along
/// z), with the desired force f_e (orange) and the rendered force f (blue) every 50 ms in
/// contact, the contact points (where the finger met the surface) in grey, and the surface's
/// section by the plane of the path (at its median y) when the log recorded the surface.
fn path_plot(
    path: &Path,
    records: &[DrawnPeriod],
    first_contacts: &Marks<(f64, f64)>,
    surface: Option<(u64, &RecordedSurface)>,
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (900, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let mm = |v: f64| v * 1e3;
    let (x_lo, x_hi) = span(records.iter().map(|r| mm(r.position_m[0])));
    let (z_lo, z_hi) = span(records.iter().map(|r| mm(r.position_m[2])));
    // Same scale on both axes: a force's direction is drawn as it is.
    let half = ((x_hi - x_lo).max(z_hi - z_lo) / 2.0).max(10.0);
    let (xc, zc) = ((x_lo + x_hi) / 2.0, (z_lo + z_hi) / 2.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Thimble path (x-z), desired force f_e and rendered force f",
            ("sans-serif", 18),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (xc - half)..(xc + half),
            (zc - half * 0.78)..(zc + half * 0.78),
        )
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .x_desc("x, mm")
        .y_desc("z, mm (towards the frame: down)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    chart
        .draw_series(LineSeries::new(
            records
                .iter()
                .map(|r| (mm(r.position_m[0]), mm(r.position_m[2]))),
            BLACK.stroke_width(1),
        ))
        .map_err(e(path))?
        .label("thimble path")
        .legend(line_mark(BLACK.stroke_width(1)));
    if let Some((version, surface)) = surface {
        let mut ys: Vec<f64> = records.iter().map(|r| r.position_m[1]).collect();
        ys.sort_by(f64::total_cmp);
        let y_m = ys[ys.len() / 2];
        let xs: Vec<f64> = (0..=400)
            .map(|i| (xc - half + 2.0 * half * f64::from(i) / 400.0) * 1e-3)
            .collect();
        let section = surface_section(surface, y_m, &xs);
        let z_window = (zc - half * 0.78)..(zc + half * 0.78);
        chart
            .draw_series(LineSeries::new(
                section
                    .iter()
                    .map(|&(x, z)| (mm(x), mm(z)))
                    .filter(|(_, z)| z_window.contains(z)),
                BROWN.stroke_width(2),
            ))
            .map_err(e(path))?
            .label(format!(
                "surface at y = {:.0} mm (version {version})",
                mm(y_m)
            ))
            .legend(line_mark(BROWN.stroke_width(2)));
    }
    chart
        .draw_series(
            first_contacts
                .kept
                .iter()
                .map(|&(x, z)| Circle::new((mm(x), mm(z)), 3, GREY.filled())),
        )
        .map_err(e(path))?
        .label(match first_contacts.beyond {
            0 => "first contact".to_string(),
            n => format!("first contact ({n} later ones not drawn)"),
        })
        .legend(|(x, y)| Circle::new((x, y), 3, GREY.filled()));
    // Arrows: 1 N is drawn as 5 % of the plot's width.
    let scale_mm_per_n = half * 0.1;
    let every = (records.len() / 80).max(1);
    let arrows = |pick: fn(&DrawnPeriod) -> [f64; 3]| -> Vec<[(f64, f64); 2]> {
        records
            .iter()
            .step_by(every)
            .filter(|r| r.in_contact)
            .map(|r| {
                let (x, z) = (mm(r.position_m[0]), mm(r.position_m[2]));
                let f = pick(r);
                [
                    (x, z),
                    (x + f[0] * scale_mm_per_n, z + f[2] * scale_mm_per_n),
                ]
            })
            .collect()
    };
    chart
        .draw_series(
            arrows(|r| r.desired_force_n)
                .into_iter()
                .map(|a| PathElement::new(a, ORANGE.stroke_width(2))),
        )
        .map_err(e(path))?
        .label(format!("desired force f_e (1 N = {scale_mm_per_n:.1} mm)"))
        .legend(line_mark(ORANGE.stroke_width(2)));
    chart
        .draw_series(
            arrows(|r| r.rendered_force_n)
                .into_iter()
                .map(|a| PathElement::new(a, WIRE_COLOURS[0].stroke_width(1))),
        )
        .map_err(e(path))?
        .label("rendered force f")
        .legend(line_mark(WIRE_COLOURS[0].stroke_width(1)));
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(e(path))?;
    Ok(())
}

/// A panel with time (s) from the session's start on x, `y` on y, captioned and with its grid.
fn time_chart<'a>(
    area: &DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>,
    caption: impl AsRef<str>,
    t_end: f64,
    y: core::ops::Range<f64>,
    y_desc: &str,
    path: &Path,
) -> Result<TimeChart<'a>, PlotError> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16))
        .margin(8)
        .x_label_area_size(35)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_end.max(1e-3), y)
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc(y_desc)
        .label_style(("sans-serif", 12))
        .draw()
        .map_err(e(path))?;
    Ok(chart)
}

/// Vertical lines at the safety events, labelled with the new state.
fn draw_events(
    chart: &mut TimeChart<'_>,
    events: &Marks<(f64, SafetyState)>,
    (y_lo, y_hi): (f64, f64),
) -> Result<(), String> {
    for &(t, state) in &events.kept {
        let colour = if state == SafetyState::Normal {
            WIRE_COLOURS[2]
        } else {
            RGBColor(148, 103, 189)
        };
        chart
            .draw_series(LineSeries::new(
                [(t, y_lo), (t, y_hi)],
                colour.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        chart
            .draw_series(std::iter::once(Text::new(
                state.as_str().to_string(),
                (t, y_hi),
                ("sans-serif", 12).into_font().color(&colour),
            )))
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn tensions_plot(
    path: &Path,
    records: &[DrawnPeriod],
    t0: f64,
    limits: TensionLimits,
    events: &Marks<(f64, SafetyState)>,
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let panels = root.split_evenly((3, 1));
    let t_end = records[records.len() - 1].time_s - t0;
    for (w, panel) in panels.iter().enumerate() {
        let (_, hi) = span(
            records
                .iter()
                .flat_map(|r| [r.tension_measured_n[w], r.tension_setpoint_n[w]]),
        );
        let y_hi = hi.max(limits.t_min_n * 2.0).min(limits.t_max_n * 1.1);
        let mut chart = time_chart(
            panel,
            format!("wire {w}: tension"),
            t_end,
            -0.1..y_hi,
            "N",
            path,
        )?;
        chart
            .draw_series(LineSeries::new(
                records
                    .iter()
                    .map(|r| (r.time_s - t0, r.tension_setpoint_n[w])),
                ORANGE.stroke_width(1),
            ))
            .map_err(e(path))?
            .label("set-point")
            .legend(line_mark(ORANGE.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(
                records
                    .iter()
                    .map(|r| (r.time_s - t0, r.tension_measured_n[w])),
                WIRE_COLOURS[w].stroke_width(1),
            ))
            .map_err(e(path))?
            .label("measured")
            .legend(line_mark(WIRE_COLOURS[w].stroke_width(2)));
        for (value, name) in [(limits.t_min_n, "t_min"), (limits.t_max_n, "t_max")] {
            if value <= y_hi {
                chart
                    .draw_series(LineSeries::new(
                        [(0.0, value), (t_end, value)],
                        GREY.stroke_width(1),
                    ))
                    .map_err(e(path))?
                    .label(format!("{name} = {value} N"))
                    .legend(line_mark(GREY.stroke_width(1)));
            }
        }
        draw_events(&mut chart, events, (-0.1, y_hi)).map_err(e(path))?;
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    }
    root.present().map_err(e(path))?;
    Ok(())
}

fn forces_plot(
    path: &Path,
    records: &[DrawnPeriod],
    t0: f64,
    events: &Marks<(f64, SafetyState)>,
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (1000, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let (top, bottom) = root.split_vertically(420);
    let t_end = records[records.len() - 1].time_s - t0;
    let (_, f_hi) = span(
        records
            .iter()
            .flat_map(|r| [norm(r.desired_force_n), norm(r.rendered_force_n)]),
    );
    let mut chart = time_chart(
        &top,
        "Desired force |f_e| and rendered force |f|",
        t_end,
        0.0..f_hi.max(0.1),
        "N",
        path,
    )?;
    chart
        .draw_series(LineSeries::new(
            records
                .iter()
                .map(|r| (r.time_s - t0, norm(r.desired_force_n))),
            ORANGE.stroke_width(2),
        ))
        .map_err(e(path))?
        .label("|f_e| desired")
        .legend(line_mark(ORANGE.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            records
                .iter()
                .map(|r| (r.time_s - t0, norm(r.rendered_force_n))),
            WIRE_COLOURS[0].stroke_width(1),
        ))
        .map_err(e(path))?
        .label("|f| rendered by the set-points")
        .legend(line_mark(WIRE_COLOURS[0].stroke_width(2)));
    draw_events(&mut chart, events, (0.0, f_hi.max(0.1))).map_err(e(path))?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    let mut chart = time_chart(
        &bottom,
        "Index V (eq. 8) in contact: rendered along desired / |desired|",
        t_end,
        -0.1..1.3,
        "V",
        path,
    )?;
    chart
        .draw_series(records.iter().filter_map(|r| {
            let v = r.contact_v()?;
            Some(Circle::new(
                (r.time_s - t0, v.clamp(-0.1, 1.3)),
                1,
                WIRE_COLOURS[2].filled(),
            ))
        }))
        .map_err(e(path))?;
    root.present().map_err(e(path))?;
    Ok(())
}

/// `h` in `bins` bars of equal width up to its 99.9th percentile (the last bar holds the
/// 0.1 % beyond), µs: (the bars' width, each bar's left edge and count).
fn histogram(h: &Histogram, bins: usize) -> (f64, Vec<(f64, u64)>) {
    let top = (h.quantile_ns(0.999) as f64 * 1e-3).max(1.0);
    let width = top / bins as f64;
    let mut counts = vec![0u64; bins];
    for (lower_ns, upper_ns, count) in h.buckets() {
        // A bucket is placed by its middle (its values are within a microsecond below 2 ms).
        let middle_us = (lower_ns as f64 + upper_ns.min(h.max_ns().max(lower_ns)) as f64) * 0.5e-3;
        counts[((middle_us / width) as usize).min(bins - 1)] += count;
    }
    (
        width,
        counts
            .into_iter()
            .enumerate()
            .map(|(i, c)| (i as f64 * width, c))
            .collect(),
    )
}

fn timing_plot(path: &Path, [wake, compute]: [&Histogram; 2]) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (1000, 500)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let (left, right) = root.split_horizontally(500);
    for (area, values, title, colour) in [
        (&left, wake, "wake-up latency", WIRE_COLOURS[0]),
        (&right, compute, "compute time", WIRE_COLOURS[1]),
    ] {
        let (width, bins) = histogram(values, 60);
        let max_count = bins.iter().map(|b| b.1).max().unwrap_or(1).max(1);
        let x_hi = bins.last().map_or(1.0, |b| b.0 + width);
        let mut chart = ChartBuilder::on(area)
            .caption(
                format!("{title} (the last bar: the 0.1 % beyond)"),
                ("sans-serif", 16),
            )
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_hi, (1u64..max_count * 2).log_scale())
            .map_err(e(path))?;
        chart
            .configure_mesh()
            .x_desc("µs")
            .y_desc("periods")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(e(path))?;
        chart
            .draw_series(bins.iter().filter(|b| b.1 > 0).map(|&(x, c)| {
                Rectangle::new([(x, 1), (x + width, c.max(1))], colour.mix(0.7).filled())
            }))
            .map_err(e(path))?;
    }
    root.present().map_err(e(path))?;
    Ok(())
}

/// `replay.png`: per wire, the recorded tension set-point against the replayed one, and the
/// recorded |f| against the replayed one, with the first divergence marked.
pub fn replay_plot(
    path: &Path,
    pairs: &[(DrawnPeriod, DrawnPeriod)],
    first_divergence_s: Option<f64>,
) -> Result<(), PlotError> {
    if pairs.is_empty() {
        return Err("nothing replayed to plot".into());
    }
    let recorded: Vec<&DrawnPeriod> = pairs.iter().map(|p| &p.0).collect();
    let replayed: Vec<&DrawnPeriod> = pairs.iter().map(|p| &p.1).collect();
    register_font();
    let root = BitMapBackend::new(path, (1000, 1100)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let panels = root.split_evenly((4, 1));
    let t0 = recorded[0].time_s;
    let t_end = recorded[recorded.len() - 1].time_s - t0;
    let t = |r: &DrawnPeriod| r.time_s - t0;
    type Pick = Box<dyn Fn(&DrawnPeriod) -> f64>;
    let series: Vec<(String, &str, Pick)> = (0..3)
        .map(|w| {
            (
                format!("wire {w}: tension set-point, recorded and replayed"),
                "N",
                Box::new(move |r: &DrawnPeriod| r.tension_setpoint_n[w]) as Pick,
            )
        })
        .chain(std::iter::once((
            "|f|, the force the set-points render: recorded and replayed".to_string(),
            "N",
            Box::new(|r: &DrawnPeriod| norm(r.rendered_force_n)) as Pick,
        )))
        .collect();
    for (panel, (caption, unit, pick)) in panels.iter().zip(&series) {
        let (lo, hi) = span(recorded.iter().chain(&replayed).map(|r| pick(r)));
        let mut chart = time_chart(panel, caption, t_end, lo..hi, unit, path)?;
        // The recorded line three pixels thick, as three one-pixel lines: a thick line's
        // mitred corners would spike far out of the panel where the tension is noisy.
        let pixel = (hi - lo) / f64::from(chart.plotting_area().dim_in_pixel().1.max(1));
        for offset in [-pixel, pixel] {
            chart
                .draw_series(LineSeries::new(
                    recorded.iter().map(|r| (t(r), pick(r) + offset)),
                    GREY.stroke_width(1),
                ))
                .map_err(e(path))?;
        }
        chart
            .draw_series(LineSeries::new(
                recorded.iter().map(|r| (t(r), pick(r))),
                GREY.stroke_width(1),
            ))
            .map_err(e(path))?
            .label("recorded")
            .legend(line_mark(GREY.stroke_width(3)));
        chart
            .draw_series(LineSeries::new(
                replayed.iter().map(|r| (t(r), pick(r))),
                ORANGE.stroke_width(1),
            ))
            .map_err(e(path))?
            .label("replayed")
            .legend(line_mark(ORANGE.stroke_width(1)));
        if let Some(td) = first_divergence_s {
            chart
                .draw_series(LineSeries::new(
                    [(td - t0, lo), (td - t0, hi)],
                    RGBColor(148, 103, 189).stroke_width(1),
                ))
                .map_err(e(path))?
                .label("first divergence")
                .legend(line_mark(RGBColor(148, 103, 189).stroke_width(1)));
        }
        draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    }
    root.present().map_err(e(path))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_runtime::cycle::CycleRecord;

    #[test]
    fn an_empty_log_is_a_clear_error_and_writes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let limits = TensionLimits {
            t_min_n: 0.3,
            t_max_n: 15.0,
        };
        let data = SessionFigureData::default();
        let err = write_all(&dir.path().join("plots"), &data, None, limits).unwrap_err();
        assert!(err.to_string().contains("no records"), "{err}");
        assert!(!dir.path().join("plots").exists());
    }

    #[test]
    fn the_histogram_keeps_every_value_and_bins_the_tail_last() {
        let mut h = Histogram::new();
        for v in (0..1000u64).map(|us| us * 1000).chain([1_000_000_000]) {
            h.record(v);
        }
        let (width, bins) = histogram(&h, 10);
        assert_eq!(bins.iter().map(|b| b.1).sum::<u64>(), 1001);
        assert!(width > 90.0 && width < 110.0, "{width}");
        assert!(bins[9].1 >= 1);
        // A value lands in the bar that holds it: 0-99 µs in the first.
        assert_eq!(
            bins[0].1,
            (0..1000).filter(|us| (*us as f64 + 0.5) < width).count() as u64
        );
    }

    /// A minute at 1 kHz with noisy tensions and forces, contacts and spikes.
    fn noisy_session(periods: u64) -> Vec<CycleRecord> {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut noise = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 10_000) as f64 / 10_000.0 - 0.5
        };
        (0..periods)
            .map(|i| {
                let t = i as f64 * 1e-3;
                let in_contact = (t * 0.4).sin() > 0.2;
                let push = if in_contact {
                    3.0 + 2.0 * (t * 3.0).sin()
                } else {
                    0.0
                };
                let spike = if i % 7919 == 0 { 6.0 } else { 0.0 };
                let mut r = CycleRecord {
                    cycle: i,
                    time: videt_hal::MonoTime(5_000_000_000 + i * 1_000_000),
                    in_contact,
                    position_m: [0.1 * (t * 0.3).sin(), 0.0, 0.3 + 0.02 * (t * 0.4).sin()],
                    desired_force_n: [0.0, 0.0, push],
                    rendered_force_n: [0.1 * noise(), 0.0, push + 0.3 * noise()],
                    ..CycleRecord::default()
                };
                for w in 0..3 {
                    r.tension_setpoint_n[w] = 1.0 + push * (0.3 + 0.2 * w as f64) + spike;
                    r.tension_measured_n[w] = r.tension_setpoint_n[w] + 0.4 * noise();
                }
                r
            })
            .collect()
    }

    fn differing_pixels(a: &Path, b: &Path) -> f64 {
        let (a, b) = (
            image::open(a).unwrap().to_rgb8(),
            image::open(b).unwrap().to_rgb8(),
        );
        assert_eq!(a.dimensions(), b.dimensions());
        let differ = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
        differ as f64 / a.pixels().len() as f64
    }

    #[test]
    fn a_long_session_draws_the_same_time_figures_from_the_periods_kept() {
        let dir = tempfile::tempdir().unwrap();
        let records = noisy_session(60_000);
        let mut data = SessionFigureData::default();
        records.iter().for_each(|r| data.add(r));
        let all: Vec<DrawnPeriod> = records.iter().map(DrawnPeriod::of).collect();
        let kept = data.drawn_periods();
        assert!(
            kept.len() * 4 < all.len(),
            "{} of {} kept",
            kept.len(),
            all.len()
        );
        let t0 = all[0].time_s;
        let limits = TensionLimits {
            t_min_n: 0.3,
            t_max_n: 15.0,
        };
        let events = Marks::default();
        register_font();
        let (full, thin) = (dir.path().join("full.png"), dir.path().join("thin.png"));
        tensions_plot(&full, &all, t0, limits, &events).unwrap();
        tensions_plot(&thin, &kept, t0, limits, &events).unwrap();
        let tensions = differing_pixels(&full, &thin);
        forces_plot(&full, &all, t0, &events).unwrap();
        forces_plot(&thin, &kept, t0, &events).unwrap();
        let forces = differing_pixels(&full, &thin);
        eprintln!(
            "{} of {} periods kept; pixels differing: tensions {tensions:.5}, forces {forces:.5}",
            kept.len(),
            all.len()
        );
        assert!(tensions < 0.01 && forces < 0.01, "{tensions} {forces}");
    }
}
