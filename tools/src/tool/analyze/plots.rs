//! The PNG figures of `videt analyze`, drawn with plotters (text in the font of
//! [`crate::plotting`]): planar, the V polar plots (over the field's magnitude and over the
//! algorithms); 3 wires, V over azimuth and elevation; both, a heat map of the isotropic force
//! limit over the workspace.

use std::path::{Path, PathBuf};

use nalgebra::Vector2;
use plotters::prelude::*;
use videt_control::analysis::{evaluate_direction, AnalysisSetup};
use videt_control::{Algorithm, RigPlanar, Vec3};

use super::analysis::{isotropic_grid, planar_v};
use super::request::{check_planar_point, check_spatial_point, Request, MIN_HEIGHT_M};
use crate::plotting::{register_font, write_error as e, PlotError};

/// Write every plot for the request into `dir`; returns the files written.
pub fn write_all(
    dir: &Path,
    request: &Request,
    setup: &AnalysisSetup,
) -> Result<Vec<PathBuf>, PlotError> {
    register_font();
    let mut written = Vec::new();
    match request {
        Request::Planar { rig, at_m } => {
            let path = dir.join("v_polar.png");
            let fields = if setup.field_n > 0.0 {
                (0..=4).map(|k| setup.field_n * k as f64 / 4.0).collect()
            } else {
                vec![0.0]
            };
            let curves: Vec<(String, Vec<f64>)> = fields
                .iter()
                .map(|&fc| {
                    let s = AnalysisSetup {
                        field_n: fc,
                        ..*setup
                    };
                    (
                        format!("|f_c| = {fc:.2} N"),
                        (0..360)
                            .map(|d| planar_v(rig, at_m, &s, d as f64))
                            .collect(),
                    )
                })
                .collect();
            let title = format!(
                "Index V, {}, |f_e| = {} N, x = {:.2} z = {:.2} m",
                setup.algorithm.name(),
                setup.force_n,
                at_m.x,
                at_m.y
            );
            polar_plot(&path, &title, rig, at_m, &curves)?;
            written.push(path);

            let path = dir.join("v_compare.png");
            let curves: Vec<(String, Vec<f64>)> = Algorithm::ALL
                .iter()
                .map(|&alg| {
                    let s = AnalysisSetup {
                        algorithm: alg,
                        ..*setup
                    };
                    (
                        alg.name().to_string(),
                        (0..360)
                            .map(|d| planar_v(rig, at_m, &s, d as f64))
                            .collect(),
                    )
                })
                .collect();
            let title = format!(
                "Index V by algorithm, |f_c| = {} N, |f_e| = {} N",
                setup.field_n, setup.force_n
            );
            polar_plot(&path, &title, rig, at_m, &curves)?;
            written.push(path);

            let path = dir.join("isotropic_heatmap.png");
            let [g0, g1] = rig.guides_x_m();
            let (x_lo, x_hi) = (g0.min(g1) - 0.25, g0.max(g1) + 0.25);
            let z_hi = (at_m.y * 1.6).max(0.6);
            let xs = linspace(x_lo, x_hi, 220);
            let zs = linspace(MIN_HEIGHT_M, z_hi, 160);
            let grid = isotropic_grid(rig, Vector2::new, setup, &xs, &zs, |p| {
                check_planar_point(rig, p).is_ok()
            });
            let title = format!(
                "Isotropic force limit (N), {}, |f_c| = {} N, t_min = {} N (x-z plane)",
                setup.algorithm.name(),
                setup.field_n,
                setup.limits.t_min_n
            );
            let marks = vec![(g0, 0.0), (g1, 0.0)];
            heatmap(
                &path,
                &title,
                ("x (m)", "z (m)"),
                &xs,
                &zs,
                &grid,
                &marks,
                (at_m.x, at_m.y),
            )?;
            written.push(path);
        }
        Request::Spatial { rig, at_m } => {
            let map = rig.wire_map(at_m).expect("checked regular");
            let path = dir.join("v_sphere.png");
            let az: Vec<f64> = (0..72).map(|k| k as f64 * 5.0).collect();
            let el: Vec<f64> = (0..=36).map(|k| -90.0 + k as f64 * 5.0).collect();
            let grid: Vec<Vec<Option<f64>>> = el
                .iter()
                .map(|&e| {
                    az.iter()
                        .map(|&a| {
                            let (a, e) = (a.to_radians(), e.to_radians());
                            let dir = Vec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
                            Some(evaluate_direction(&map, &dir, setup).v)
                        })
                        .collect()
                })
                .collect();
            let title = format!(
                "Index V, {}, |f_c| = {} N, |f_e| = {} N, at ({:.2}, {:.2}, {:.2}) m",
                setup.algorithm.name(),
                setup.field_n,
                setup.force_n,
                at_m.x,
                at_m.y,
                at_m.z
            );
            heatmap(
                &path,
                &title,
                (
                    "azimuth (deg, from +x towards +y)",
                    "elevation (deg, towards +z)",
                ),
                &az,
                &el,
                &grid,
                &[],
                (f64::NAN, f64::NAN),
            )?;
            written.push(path);

            let path = dir.join("isotropic_heatmap.png");
            let g = rig.guides_m();
            let x_lo = g.iter().map(|p| p.x).fold(f64::INFINITY, f64::min) - 0.25;
            let x_hi = g.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max) + 0.25;
            let y_lo = g.iter().map(|p| p.y).fold(f64::INFINITY, f64::min) - 0.25;
            let y_hi = g.iter().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max) + 0.25;
            let xs = linspace(x_lo, x_hi, 200);
            let ys = linspace(y_lo, y_hi, 200);
            let z = at_m.z;
            let grid = isotropic_grid(
                rig,
                |x, y| Vec3::new(x, y, z),
                setup,
                &xs,
                &ys,
                |p| check_spatial_point(rig, p).is_ok(),
            );
            let title = format!(
                "Isotropic force limit (N), {}, |f_c| = {} N, slice z = {:.2} m",
                setup.algorithm.name(),
                setup.field_n,
                z
            );
            let marks: Vec<(f64, f64)> = g.iter().map(|p| (p.x, p.y)).collect();
            heatmap(
                &path,
                &title,
                ("x (m)", "y (m)"),
                &xs,
                &ys,
                &grid,
                &marks,
                (at_m.x, at_m.y),
            )?;
            written.push(path);
        }
    }
    Ok(written)
}

fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| lo + (hi - lo) * k as f64 / (n - 1) as f64)
        .collect()
}

const SERIES: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// V over direction as a polar curve (radius = max(V, 0)), with the wires drawn.
fn polar_plot(
    path: &Path,
    title: &str,
    rig: &RigPlanar,
    at: &Vector2<f64>,
    curves: &[(String, Vec<f64>)],
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (760, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let r = 1.3;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(20)
        .build_cartesian_2d(-r..r, -r..r)
        .map_err(e(path))?;
    let grey = RGBColor(200, 200, 200);
    for ring in [0.25, 0.5, 0.75, 1.0, 1.25] {
        let pts: Vec<(f64, f64)> = (0..=360)
            .map(|d| {
                let a = (d as f64).to_radians();
                (ring * a.cos(), ring * a.sin())
            })
            .collect();
        let style = if ring == 1.0 {
            RGBColor(120, 120, 120).stroke_width(2)
        } else {
            grey.stroke_width(1)
        };
        chart
            .draw_series(LineSeries::new(pts, style))
            .map_err(e(path))?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{ring}"),
                (
                    ring * std::f64::consts::FRAC_1_SQRT_2 + 0.01,
                    ring * std::f64::consts::FRAC_1_SQRT_2,
                ),
                ("sans-serif", 13)
                    .into_font()
                    .color(&RGBColor(110, 110, 110)),
            )))
            .map_err(e(path))?;
    }
    for deg in (0..360).step_by(30) {
        let a = (deg as f64).to_radians();
        chart
            .draw_series(LineSeries::new(
                vec![(0.0, 0.0), (1.25 * a.cos(), 1.25 * a.sin())],
                grey.stroke_width(1),
            ))
            .map_err(e(path))?;
        chart
            .draw_series(std::iter::once(Text::new(
                format!("{deg}°"),
                (1.29 * a.cos() - 0.04, 1.29 * a.sin() + 0.02),
                ("sans-serif", 14).into_font(),
            )))
            .map_err(e(path))?;
    }
    // The wires: from the thimble towards each guide (the directions they can pull).
    if let Some(map) = rig.wire_map(at) {
        for i in 0..2 {
            let u = map.pull_direction(i);
            chart
                .draw_series(LineSeries::new(
                    vec![(0.0, 0.0), (1.3 * u.x, 1.3 * u.y)],
                    BLACK.stroke_width(3),
                ))
                .map_err(e(path))?;
            chart
                .draw_series(std::iter::once(Text::new(
                    format!("wire {i}"),
                    (1.05 * u.x + 0.02, 1.05 * u.y),
                    ("sans-serif", 15).into_font(),
                )))
                .map_err(e(path))?;
        }
    }
    for (k, (label, v)) in curves.iter().enumerate() {
        let colour = SERIES[k % SERIES.len()];
        let pts: Vec<(f64, f64)> = (0..=360)
            .map(|d| {
                let a = (d as f64).to_radians();
                let rad = v[d % 360].clamp(0.0, 1.25);
                (rad * a.cos(), rad * a.sin())
            })
            .collect();
        // Earlier series wider, so that curves that coincide stay visible.
        let width = 2 + 2 * (curves.len() - 1 - k) as u32;
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(width)))
            .map_err(e(path))?
            .label(label.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    root.present().map_err(e(path))?;
    Ok(())
}

/// A viridis-like colour for `t` in [0, 1].
fn colour(t: f64) -> RGBColor {
    const STOPS: [(f64, f64, f64); 6] = [
        (68.0, 1.0, 84.0),
        (65.0, 68.0, 135.0),
        (42.0, 120.0, 142.0),
        (34.0, 168.0, 132.0),
        (122.0, 209.0, 81.0),
        (253.0, 231.0, 37.0),
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let (a, b) = (STOPS[i], STOPS[i + 1]);
    let mix = |x: f64, y: f64| (x + (y - x) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// A heat map of `grid[row y][col x]`; `None` cells (outside the workspace) are light grey.
#[allow(clippy::too_many_arguments)]
fn heatmap(
    path: &Path,
    title: &str,
    (x_label, y_label): (&str, &str),
    xs: &[f64],
    ys: &[f64],
    grid: &[Vec<Option<f64>>],
    marks: &[(f64, f64)],
    point: (f64, f64),
) -> Result<(), PlotError> {
    let root = BitMapBackend::new(path, (900, 700)).into_drawing_area();
    root.fill(&WHITE).map_err(e(path))?;
    let (main, bar) = root.split_horizontally(780);
    let max = grid
        .iter()
        .flatten()
        .flatten()
        .fold(0.0f64, |m, &v| m.max(v));
    let min = grid
        .iter()
        .flatten()
        .flatten()
        .fold(f64::INFINITY, |m, &v| m.min(v));
    // Scale from 0 unless values are clearly negative (V with a tension floor).
    let min = if min > -1e-9 { 0.0 } else { min };
    let span = if max - min > 1e-12 { max - min } else { 1.0 };
    let dx = (xs[1] - xs[0]) / 2.0;
    let dy = (ys[1] - ys[0]) / 2.0;
    let mut chart = ChartBuilder::on(&main)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (xs[0] - dx)..(xs[xs.len() - 1] + dx),
            (ys[0] - dy)..(ys[ys.len() - 1] + dy),
        )
        .map_err(e(path))?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e(path))?;
    let cells = ys.iter().zip(grid).flat_map(|(&y, row)| {
        xs.iter().zip(row).map(move |(&x, v)| {
            let c = match v {
                Some(v) => colour((v - min) / span),
                None => RGBColor(225, 225, 225),
            };
            Rectangle::new([(x - dx, y - dy), (x + dx, y + dy)], c.filled())
        })
    });
    chart.draw_series(cells).map_err(e(path))?;
    chart
        .draw_series(
            marks
                .iter()
                .map(|&(x, y)| TriangleMarker::new((x, y), 9, RED.filled())),
        )
        .map_err(e(path))?;
    if point.0.is_finite() {
        chart
            .draw_series(std::iter::once(Cross::new(point, 8, WHITE.stroke_width(3))))
            .map_err(e(path))?;
    }
    // Colour bar.
    let mut bar_chart = ChartBuilder::on(&bar)
        .margin_top(60)
        .margin_bottom(60)
        .margin_right(10)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..1.0, min..(min + span))
        .map_err(e(path))?;
    bar_chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .label_style(("sans-serif", 13))
        .draw()
        .map_err(e(path))?;
    let steps = 100;
    bar_chart
        .draw_series((0..steps).map(|k| {
            let a = min + span * k as f64 / steps as f64;
            let b = min + span * (k + 1) as f64 / steps as f64;
            Rectangle::new(
                [(0.0, a), (1.0, b)],
                colour(k as f64 / (steps - 1) as f64).filled(),
            )
        }))
        .map_err(e(path))?;
    root.present().map_err(e(path))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tool::analyze::tests::args;
    use crate::tool::analyze::{parse_request, parse_setup};

    #[test]
    fn plots_are_written() {
        let dir = tempfile::tempdir().unwrap();
        for line in [
            &["--planar", "--fc", "2"][..],
            &["--at", "0.2,0.1,0.3", "--algorithm", "QP", "--fc", "1"][..],
        ] {
            let a = args(line);
            let written = write_all(
                dir.path(),
                &parse_request(&a).unwrap(),
                &parse_setup(&a).unwrap(),
            )
            .unwrap();
            for p in written {
                assert!(
                    std::fs::metadata(&p).unwrap().len() > 1000,
                    "{}",
                    p.display()
                );
            }
        }
    }
}
