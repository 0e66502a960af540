//! The bench's figures as PNG: rendered stiffness against the normal's angle (P1, P2, by
//! region), the Z-width against damping (per sensor and rate), and penetration against the
//! pushing force. Each carries the configuration it came from in its caption.

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use super::{BenchReport, Region};
use crate::plotting::{draw_legend, line_mark, register_font, write_error as e, PlotError};

const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Write the three figures into `dir`; returns the files written.
pub fn write_all(dir: &Path, report: &BenchReport) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    std::fs::create_dir_all(dir).map_err(e(dir))?;
    let mut written = Vec::new();
    let setup = format!(
        "K {} N/m, B {} N·s/m, {} Hz, {}",
        report.control.stiffness_n_per_m,
        report.control.damping_n_s_per_m,
        report.control.rate_hz,
        report.sensor.label()
    );
    let path = dir.join("stiffness.png");
    stiffness(&path, report, &setup)?;
    written.push(path);
    let path = dir.join("zwidth.png");
    zwidth(&path, report)?;
    written.push(path);
    let path = dir.join("pop_through.png");
    pop_through(&path, report, &setup)?;
    written.push(path);
    Ok(written)
}

fn stiffness(path: &Path, report: &BenchReport, setup: &str) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let y_max = report
        .stiffness
        .iter()
        .map(|r| r.ratio)
        .filter(|r| r.is_finite())
        .fold(1.2f64, f64::max)
        .min(3.0);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("Rendered / programmed stiffness ({setup})"),
            ("sans-serif", 17),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(-5.0f64..185.0, -0.1f64..y_max + 0.1)
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .x_desc("angle of the surface normal from the frame's axis, degrees")
        .y_desc("rendered / programmed stiffness")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    let series = [
        ("P1", Region::A),
        ("P1", Region::B),
        ("P1", Region::C),
        ("P2", Region::A),
        ("P2", Region::B),
        ("P2", Region::C),
    ];
    for (k, (algorithm, region)) in series.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let points: Vec<(f64, f64)> = report
            .stiffness
            .iter()
            .filter(|r| r.algorithm == *algorithm && r.region == *region && r.ratio.is_finite())
            .map(|r| (r.polar_deg, r.ratio.clamp(-0.1, y_max + 0.1)))
            .collect();
        if points.is_empty() {
            continue;
        }
        let label = format!("{algorithm}, region {region:?}");
        if *algorithm == "P1" {
            chart
                .draw_series(points.iter().map(|&p| Circle::new(p, 5, colour.filled())))
                .map_err(e(path))?
                .label(label)
                .legend(move |(x, y)| Circle::new((x, y), 5, colour.filled()));
        } else {
            chart
                .draw_series(
                    points
                        .iter()
                        .map(|&p| Cross::new(p, 6, colour.stroke_width(2))),
                )
                .map_err(e(path))?
                .label(label)
                .legend(move |(x, y)| Cross::new((x, y), 6, colour.stroke_width(2)));
        }
    }
    chart
        .draw_series(LineSeries::new(
            [(-5.0, 1.0), (185.0, 1.0)],
            BLACK.stroke_width(1),
        ))
        .map_err(e(path))?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    root.present().map_err(e(path))?;
    Ok(())
}

/// A Z-width curve: its name, its colour's index, whether it is the configured rendering, and
/// its points (damping, stiffness).
type Curve = (String, usize, bool, Vec<(f64, f64)>);

fn zwidth(path: &Path, report: &BenchReport) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let (k_lo, k_hi) = super::ZWIDTH_RANGE_N_PER_M;
    let b_max = report
        .zwidth
        .iter()
        .map(|r| r.damping_n_s_per_m)
        .fold(1.0f64, f64::max);
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Z-width before (thin) and with (thick) the integral's gate and stretch correction",
            ("sans-serif", 17),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(-0.5f64..b_max + 0.5, (k_lo * 0.8..k_hi * 1.25).log_scale())
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .x_desc("wall damping B, N·s/m")
        .y_desc("largest stable stiffness K, N/m")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    // One colour per parts, sensor and rate; thin lines before the integral's gate and the
    // stretch correction, thick ones with the configured rendering.
    let mut setups: Vec<String> = Vec::new();
    let mut curves: Vec<Curve> = Vec::new();
    for row in report
        .zwidth
        .iter()
        .filter(|r| r.region == super::Region::A)
    {
        let setup = match row.parts {
            super::rig::Parts::Ideal => format!("ideal parts, {} Hz", row.rate_hz),
            super::rig::Parts::Faithful => format!("{}, {} Hz", row.sensor, row.rate_hz),
        };
        let colour = match setups.iter().position(|s| *s == setup) {
            Some(i) => i,
            None => {
                setups.push(setup.clone());
                setups.len() - 1
            }
        };
        let gated = row.rendering != super::Rendering::BEFORE;
        let name = if gated {
            format!("{setup}, now")
        } else {
            format!("{setup}, before")
        };
        let k = row.max_stable_n_per_m.unwrap_or(k_lo * 0.8);
        match curves.iter_mut().find(|(n, ..)| *n == name) {
            Some((.., pts)) => pts.push((row.damping_n_s_per_m, k)),
            None => curves.push((name, colour, gated, vec![(row.damping_n_s_per_m, k)])),
        }
    }
    for (name, colour, gated, pts) in curves {
        let colour = PALETTE[colour % PALETTE.len()];
        let width = if gated { 3 } else { 1 };
        chart
            .draw_series(LineSeries::new(pts.clone(), colour.stroke_width(width)))
            .map_err(e(path))?
            .label(name)
            .legend(line_mark(colour.stroke_width(width)));
        chart
            .draw_series(
                pts.iter()
                    .map(|&p| Circle::new(p, 2 + width, colour.filled())),
            )
            .map_err(e(path))?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::LowerRight, path)?;
    root.present().map_err(e(path))?;
    Ok(())
}

fn pop_through(path: &Path, report: &BenchReport, setup: &str) -> Result<(), PlotError> {
    let p = &report.pop_through;
    let root = BitMapBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let x_max = p.pushes.iter().map(|r| r.push_n).fold(1.0f64, f64::max) * 1.1;
    let y_max = p
        .pushes
        .iter()
        .map(|r| r.penetration_mm)
        .fold(p.feature_depth_mm, f64::max)
        * 1.15;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("Penetration against the pushing force ({setup})"),
            ("sans-serif", 17),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0f64..x_max, 0.0f64..y_max)
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .x_desc("the finger's pushing force, N")
        .y_desc("penetration, mm")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    let pts: Vec<(f64, f64)> = p
        .pushes
        .iter()
        .map(|r| (r.push_n, r.penetration_mm))
        .collect();
    chart
        .draw_series(LineSeries::new(pts, PALETTE[0].stroke_width(2)))
        .map_err(e(path))?
        .label("penetration")
        .legend(line_mark(PALETTE[0].stroke_width(2)));
    chart
        .draw_series(
            p.pushes
                .iter()
                .filter(|r| r.saturated)
                .map(|r| Cross::new((r.push_n, r.penetration_mm), 7, PALETTE[1].stroke_width(2))),
        )
        .map_err(e(path))?
        .label("a wire at its maximum tension")
        .legend(|(x, y)| Cross::new((x, y), 6, PALETTE[1].stroke_width(2)));
    chart
        .draw_series(LineSeries::new(
            [(0.0, p.feature_depth_mm), (x_max, p.feature_depth_mm)],
            PALETTE[7].stroke_width(1),
        ))
        .map_err(e(path))?
        .label(format!("relief feature {:.0} mm", p.feature_depth_mm))
        .legend(line_mark(PALETTE[7].stroke_width(1)));
    chart
        .draw_series(LineSeries::new(
            [(p.wearer_push_n, 0.0), (p.wearer_push_n, y_max)],
            PALETTE[2].stroke_width(1),
        ))
        .map_err(e(path))?
        .label(format!("the wearer's push, {:.1} N", p.wearer_push_n))
        .legend(line_mark(PALETTE[2].stroke_width(1)));
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, path)?;
    root.present().map_err(e(path))?;
    Ok(())
}
