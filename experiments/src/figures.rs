//! The figures, drawn as the paper draws them, to PNG: the x-z plane with the surface, the
//! thimble's path and the forces the wires apply as arrows (Figs. 18, 22, 23), the wires dotted
//! at two positions (Fig. 18), and the force set-points and measured forces over time (Fig. 22).
//! Text is DejaVu Sans (the `dejavu` crate). Every file is written to a temporary name in the
//! same directory and renamed into place, so a reader never sees half a figure.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use videt_control::planar::Vec2;
use videt_control::{Profile, Vec3, WireDevice};

use crate::closed_loop::{Run, Sample};
use crate::fig18::{fig18, Fig18, Fig18Summary};
use crate::fig22::{fig22, Fig22, Fig22Summary, RegionCSummary};
use crate::fig23::{fig23, Fig23, Fig23Summary};
use crate::geometry::PathStats;
use crate::ExperimentError;

/// File name of Fig. 18.
pub const FIG18_FILE: &str = "fig18_planar_p1_profile.png";
/// File name of Fig. 22.
pub const FIG22_FILE: &str = "fig22_planar_region_c_field.png";
/// File name of Fig. 23.
pub const FIG23_FILE: &str = "fig23_one_wire_contour.png";
/// File name of the summary.
pub const SUMMARY_FILE: &str = "summary.txt";

/// Force arrows: metres of arrow per newton.
const ARROW_M_PER_N: f64 = 0.01;

const BLUE: RGBColor = RGBColor(31, 119, 180);
const RED_F: RGBColor = RGBColor(214, 39, 40);
const GREEN_F: RGBColor = RGBColor(44, 160, 44);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const GREY: RGBColor = RGBColor(127, 127, 127);
const SOLID_FILL: RGBColor = RGBColor(222, 222, 222);

/// A curve of Fig. 22's time plot: the run, the value plotted, colour, width, label.
type TimeSeries<'a> = (&'a Run<2>, fn(&Sample<2>) -> f64, RGBColor, u32, &'a str);

type XzChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Register the figures' font under `"sans-serif"` (once per process).
fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font shipped by the crate; a failure would only lose
        // the text of the figures.
        let _ = plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            dejavu::sans::regular(),
        );
    });
}

fn plot_error<E: std::fmt::Display>(path: &Path) -> impl FnOnce(E) -> ExperimentError + '_ {
    move |e| ExperimentError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// A temporary sibling of `path` with the same extension (the bitmap encoder picks the format
/// from it).
fn temporary_sibling(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".tmp-{}-{name}", std::process::id()))
}

/// Write `path` atomically: `write` fills a temporary file in the same directory, which is then
/// renamed over `path`. On failure the temporary file is removed.
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), ExperimentError>,
) -> Result<(), ExperimentError> {
    let tmp = temporary_sibling(path);
    let result = write(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).map_err(|source| ExperimentError::Io {
            path: path.to_path_buf(),
            source,
        })
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Run the three experiments and write their figures and `summary.txt` into `dir` (created if
/// missing). Returns the files written.
pub fn write_figures(dir: &Path) -> Result<Vec<PathBuf>, ExperimentError> {
    let f18 = fig18()?;
    let f22 = fig22()?;
    let f23 = fig23()?;
    write_figures_of(dir, &f18, &f22, &f23)
}

/// Write the figures and `summary.txt` of experiments already run into `dir` (created if
/// missing). Returns the files written.
pub fn write_figures_of(
    dir: &Path,
    f18: &Fig18,
    f22: &Fig22,
    f23: &Fig23,
) -> Result<Vec<PathBuf>, ExperimentError> {
    register_font();
    std::fs::create_dir_all(dir).map_err(|source| ExperimentError::Io {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::new();
    let path = dir.join(FIG18_FILE);
    write_atomically(&path, |tmp| draw_fig18(tmp, f18))?;
    written.push(path);
    let path = dir.join(FIG22_FILE);
    write_atomically(&path, |tmp| draw_fig22(tmp, f22))?;
    written.push(path);
    let path = dir.join(FIG23_FILE);
    write_atomically(&path, |tmp| draw_fig23(tmp, f23))?;
    written.push(path);
    let path = dir.join(SUMMARY_FILE);
    let text = summary_text(&f18.summary, &f22.summary, &f23.summary);
    write_atomically(&path, |tmp| {
        std::fs::write(tmp, text.as_bytes()).map_err(|source| ExperimentError::Io {
            path: tmp.to_path_buf(),
            source,
        })
    })?;
    written.push(path);
    Ok(written)
}

fn mm(m: f64) -> String {
    format!("{:.2} mm", m * 1e3)
}

fn path_lines(out: &mut String, p: &PathStats) {
    let _ = writeln!(
        out,
        "  in contact: {:.1} % of the time\n  distance from the surface: max {}, RMS {}; \
         largest gap out of contact {}\n  penetration in contact: mean {}, 95th percentile {}, max {}",
        100.0 * p.contact_fraction,
        mm(p.max_distance_m),
        mm(p.rms_distance_m),
        mm(p.max_gap_m),
        mm(p.mean_depth_m),
        mm(p.p95_depth_m),
        mm(p.max_depth_m),
    );
    let coverage: Vec<String> = p
        .segment_coverage
        .iter()
        .map(|c| format!("{:.0} %", 100.0 * c))
        .collect();
    let _ = writeln!(
        out,
        "  length of each side touched: {}",
        coverage.join(", ")
    );
}

fn safety_line(out: &mut String, max_tension_n: f64, trips: usize, safe: usize) {
    let _ = writeln!(
        out,
        "  largest measured tension {max_tension_n:.2} N; safety trips {trips}, periods in the \
         safe state {safe}"
    );
}

fn region_c_lines(out: &mut String, s: &RegionCSummary) {
    let _ = writeln!(
        out,
        "- {} with |f_c| = {} N:",
        s.algorithm.name(),
        s.field_n
    );
    path_lines(out, &s.path);
    let _ = writeln!(
        out,
        "  normal in region C in {:.1} % of the contact\n  mean f_e.n (K depth) {:.3} N; mean \
         rendered reaction (f - f_c).n {:.3} N; mean V {:.3}\n  force along n: free space {:.3} \
         N, in contact {:.3} N, felt change {:.3} N",
        100.0 * s.region_c_fraction,
        s.mean_desired_n,
        s.mean_reaction_n,
        s.mean_v_index,
        s.free_force_along_n_n,
        s.contact_force_along_n_n,
        s.felt_change_n,
    );
    safety_line(out, s.max_tension_n, s.trip_periods, s.safe_state_periods);
}

/// The summaries as text: one block per figure, lengths in millimetres.
pub fn summary_text(f18: &Fig18Summary, f22: &Fig22Summary, f23: &Fig23Summary) -> String {
    let mut out = String::new();
    let c = crate::ControlConfig::EXAMPLE;
    let _ = writeln!(
        out,
        "VIDET paper, section 6, on the digital twin ({} Hz loop, example configuration: K = {} \
         N/m, B = {} N s/m, t_min = {} N, t_max = {} N)\n",
        c.rate_hz, c.stiffness_n_per_m, c.damping_n_s_per_m, c.t_min_n, c.t_max_n
    );
    let _ = writeln!(
        out,
        "Fig. 18: planar prototype, {} (|f_c| = 0), polygonal profile, {:.1} s traversal",
        f18.algorithm.name(),
        f18.traversal_s
    );
    path_lines(&mut out, &f18.path);
    let _ = writeln!(
        out,
        "  sides followed (>= 80 % touched): {} of {}\n  normal outside region A in {:.1} % of \
         the contact, deepest there {}\n  mean V: {:.3} in region A, {:.3} outside",
        f18.segments_followed,
        f18.segments,
        100.0 * f18.outside_a_fraction,
        mm(f18.max_depth_outside_a_m),
        f18.mean_v_in_a,
        f18.mean_v_outside_a,
    );
    safety_line(
        &mut out,
        f18.max_tension_n,
        f18.trip_periods,
        f18.safe_state_periods,
    );
    let _ = writeln!(
        out,
        "\nFig. 22: planar prototype, a floor with normal +z (region C)"
    );
    region_c_lines(&mut out, &f22.field);
    region_c_lines(&mut out, &f22.baseline);
    let _ = writeln!(
        out,
        "\nFig. 23: one-wire device, {}, polygonal contour, {:.1} s traversal",
        f23.algorithm.name(),
        f23.traversal_s
    );
    path_lines(&mut out, &f23.path);
    let _ = writeln!(
        out,
        "  sides explored (>= 80 % touched): {} of {}\n  off the contour's plane: max {}\n  \
         largest angle between the force and the wire {:.2e} rad; mean tension in contact {:.2} N",
        f23.sides_explored,
        f23.sides,
        mm(f23.max_off_plane_m),
        f23.max_force_angle_from_wire_rad,
        f23.mean_contact_tension_n,
    );
    safety_line(
        &mut out,
        f23.max_tension_n,
        f23.trip_periods,
        f23.safe_state_periods,
    );
    out
}

/// Pixel size of a plot of the x-z ranges with equal scales on both axes, `width` pixels of
/// plotting area wide, plus the label areas.
fn equal_aspect(x: (f64, f64), z: (f64, f64), width: u32) -> (u32, u32) {
    let h = (f64::from(width) * (z.1 - z.0) / (x.1 - x.0)).round() as u32;
    (width + 75 + 30, h + 60 + 55)
}

fn xz_chart<'a, 'b>(
    area: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    caption: &str,
    x: (f64, f64),
    z: (f64, f64),
    path: &Path,
) -> Result<XzChart<'a, 'b>, ExperimentError> {
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 17))
        .margin_left(10)
        .margin_right(20)
        .margin_top(10)
        .margin_bottom(5)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(x.0..x.1, z.0..z.1)
        .map_err(plot_error(path))?;
    chart
        .configure_mesh()
        .x_desc("x, m")
        .y_desc("z, m")
        .label_style(("sans-serif", 14))
        .light_line_style(WHITE.mix(0.0))
        .draw()
        .map_err(plot_error(path))?;
    Ok(chart)
}

/// The solid beyond a profile, as a polygon closed far enough to cover the plot's ranges.
fn solid_polygon(profile: &Profile, x: (f64, f64), z: (f64, f64)) -> Vec<(f64, f64)> {
    let v = profile.vertices();
    let mut pts: Vec<(f64, f64)> = v.iter().map(|p| (p.x, p.y)).collect();
    if profile.is_closed() {
        return pts;
    }
    // Extend the end segments to the plot's border and close around the solid side.
    let span = (x.1 - x.0) + (z.1 - z.0);
    let first_dir = (v[0] - v[1]).normalize();
    let last_dir = (v[v.len() - 1] - v[v.len() - 2]).normalize();
    let start = v[0] + first_dir * span;
    let end = v[v.len() - 1] + last_dir * span;
    pts.insert(0, (start.x, start.y));
    pts.push((end.x, end.y));
    // Walk on around the solid: its side of the end ray, then back to the start.
    let end_normal = -outward(profile, profile.segment_count() - 1);
    let start_normal = -outward(profile, 0);
    let far_end = end + end_normal * span;
    let far_start = start + start_normal * span;
    pts.push((far_end.x, far_end.y));
    // Round the far side between the two ends' solid sides (a corner of the walk).
    let between = end_normal + start_normal;
    if between.norm() > 1e-6 {
        let centre = (far_end + far_start) * 0.5;
        let far = centre + between.normalize() * (2.0 * span);
        pts.push((far.x, far.y));
    }
    pts.push((far_start.x, far_start.y));
    pts
}

fn outward(profile: &Profile, segment: usize) -> Vec2 {
    profile.outward_normal(segment)
}

fn draw_surface<'a, 'b: 'a>(
    chart: &mut XzChart<'a, 'b>,
    profile: &Profile,
    x: (f64, f64),
    z: (f64, f64),
    label: &str,
    path: &Path,
) -> Result<(), ExperimentError> {
    chart
        .draw_series(std::iter::once(Polygon::new(
            solid_polygon(profile, x, z),
            SOLID_FILL.filled(),
        )))
        .map_err(plot_error(path))?
        .label("solid")
        .legend(|(px, py)| Rectangle::new([(px, py - 5), (px + 20, py + 5)], SOLID_FILL.filled()));
    let mut line: Vec<(f64, f64)> = profile.vertices().iter().map(|p| (p.x, p.y)).collect();
    if profile.is_closed() {
        line.push(line[0]);
    }
    chart
        .draw_series(LineSeries::new(line, BLACK.stroke_width(3)))
        .map_err(plot_error(path))?
        .label(label)
        .legend(|(px, py)| PathElement::new([(px, py), (px + 20, py)], BLACK.stroke_width(3)));
    Ok(())
}

fn draw_path<'a, 'b: 'a, const N: usize>(
    chart: &mut XzChart<'a, 'b>,
    run: &Run<N>,
    window: (f64, f64),
    colour: RGBColor,
    label: &str,
    path: &Path,
) -> Result<(), ExperimentError> {
    // Only points 0.2 mm or more apart, drawn as separate segments: the bitmap backend's wide
    // strokes join consecutive segments by intersecting their edges, which fails (the stroke
    // vanishes) where they are (nearly) collinear, as a thimble's path mostly is.
    let mut points: Vec<(f64, f64)> = Vec::new();
    for s in run.window(window.0, window.1) {
        let p = (s.position_m.x, s.position_m.z);
        if points
            .last()
            .is_none_or(|q| (p.0 - q.0).hypot(p.1 - q.1) >= 2e-4)
        {
            points.push(p);
        }
    }
    let style = colour.stroke_width(2);
    chart
        .draw_series(
            points
                .windows(2)
                .map(move |w| PathElement::new(vec![w[0], w[1]], style)),
        )
        .map_err(plot_error(path))?
        .label(label)
        .legend(move |(px, py)| {
            PathElement::new([(px, py), (px + 20, py)], colour.stroke_width(2))
        });
    Ok(())
}

/// An arrow from `from` along `vector` (x-z, metres), its head a quarter of its length.
fn arrow(from: (f64, f64), vector: (f64, f64), style: ShapeStyle) -> Vec<PathElement<(f64, f64)>> {
    let to = (from.0 + vector.0, from.1 + vector.1);
    let len = (vector.0 * vector.0 + vector.1 * vector.1).sqrt();
    let mut out = vec![PathElement::new(vec![from, to], style)];
    if len > 1e-9 {
        let head = (0.3 * len).min(0.006);
        let (ux, uz) = (vector.0 / len, vector.1 / len);
        for s in [1.0f64, -1.0] {
            let (c, si) = (0.35f64.cos(), s * 0.35f64.sin());
            let (bx, bz) = (-(ux * c - uz * si), -(ux * si + uz * c));
            out.push(PathElement::new(
                vec![to, (to.0 + head * bx, to.1 + head * bz)],
                style,
            ));
        }
    }
    out
}

/// Force arrows every `every_s` seconds of `window` (forces of `force`, metres per newton
/// [`ARROW_M_PER_N`]), skipping forces below 0.05 N.
#[allow(clippy::too_many_arguments)]
fn draw_force_arrows<'a, 'b: 'a, const N: usize>(
    chart: &mut XzChart<'a, 'b>,
    run: &Run<N>,
    window: (f64, f64),
    every_s: f64,
    force: impl Fn(&Sample<N>) -> Vec3,
    colour: RGBColor,
    label: &str,
    path: &Path,
) -> Result<(), ExperimentError> {
    let stride = ((every_s / run.period_s).round() as usize).max(1);
    let mut arrows = Vec::new();
    for s in run.window(window.0, window.1).step_by(stride) {
        let f = force(s);
        if f.norm() < 0.05 {
            continue;
        }
        arrows.extend(arrow(
            (s.position_m.x, s.position_m.z),
            (f.x * ARROW_M_PER_N, f.z * ARROW_M_PER_N),
            colour.stroke_width(2),
        ));
    }
    chart
        .draw_series(arrows)
        .map_err(plot_error(path))?
        .label(label)
        .legend(move |(px, py)| {
            PathElement::new([(px, py), (px + 20, py)], colour.stroke_width(2))
        });
    Ok(())
}

fn draw_guides<'a, 'b: 'a>(
    chart: &mut XzChart<'a, 'b>,
    guides: &[Vec3],
    path: &Path,
) -> Result<(), ExperimentError> {
    chart
        .draw_series(guides.iter().map(|g| {
            Rectangle::new(
                [(g.x - 0.006, g.z - 0.006), (g.x + 0.006, g.z + 0.006)],
                BLACK.filled(),
            )
        }))
        .map_err(plot_error(path))?
        .label("wire guides")
        .legend(|(px, py)| Rectangle::new([(px + 5, py - 5), (px + 15, py + 5)], BLACK.filled()));
    Ok(())
}

fn draw_wires<'a, 'b: 'a>(
    chart: &mut XzChart<'a, 'b>,
    guides: &[Vec3],
    positions: &[Vec3],
    path: &Path,
) -> Result<(), ExperimentError> {
    let style = RGBColor(70, 70, 70).stroke_width(1);
    for (k, p) in positions.iter().enumerate() {
        for g in guides {
            let series = chart
                .draw_series(DashedLineSeries::new([(g.x, g.z), (p.x, p.z)], 3, 4, style))
                .map_err(plot_error(path))?;
            if k == 0 && std::ptr::eq(g, &guides[0]) {
                series
                    .label("wires (two positions)")
                    .legend(move |(px, py)| {
                        EmptyElement::at((px, py))
                            + PathElement::new([(0, 0), (3, 0)], style)
                            + PathElement::new([(7, 0), (10, 0)], style)
                            + PathElement::new([(14, 0), (17, 0)], style)
                    });
            }
        }
    }
    Ok(())
}

fn legend<'a, 'b: 'a>(
    chart: &mut XzChart<'a, 'b>,
    position: SeriesLabelPosition,
    path: &Path,
) -> Result<(), ExperimentError> {
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(position)
        .draw()
        .map_err(plot_error(path))?;
    Ok(())
}

/// The first contact sample of a window whose normal is within 10 degrees of `normal`.
fn first_pressing<const N: usize>(run: &Run<N>, window: (f64, f64), normal: &Vec3) -> Option<Vec3> {
    run.window(window.0, window.1)
        .find(|s| s.in_contact && s.normal.dot(normal) > 0.985 && s.depth_m > 0.001)
        .map(|s| s.position_m)
}

fn draw_fig18(path: &Path, f: &Fig18) -> Result<(), ExperimentError> {
    let (x, z) = ((-0.03, 0.55), (-0.02, 0.42));
    let size = equal_aspect(x, z, 820);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error(path))?;
    let s = &f.summary;
    let caption = format!(
        "Fig. 18 (twin): planar prototype, P1 (|f_c| = 0) following a polygonal profile; path \
         within {:.1} mm (RMS {:.1} mm)",
        s.path.max_distance_m * 1e3,
        s.path.rms_distance_m * 1e3
    );
    let mut chart = xz_chart(&root, &caption, x, z, path)?;
    draw_surface(&mut chart, &f.profile, x, z, "profile", path)?;
    let guides = f.device.guides_m();
    // The wires while pressing the wall facing -x (way out) and the one facing +x (way back).
    let mid = 0.5 * (f.traversal_s.0 + f.traversal_s.1);
    let wires: Vec<Vec3> = [
        first_pressing(&f.run, (f.traversal_s.0, mid), &-Vec3::x()),
        first_pressing(&f.run, (mid, f.traversal_s.1), &Vec3::x()),
    ]
    .into_iter()
    .flatten()
    .collect();
    draw_wires(&mut chart, &guides, &wires, path)?;
    draw_guides(&mut chart, &guides, path)?;
    draw_path(
        &mut chart,
        &f.run,
        f.traversal_s,
        BLUE,
        "thimble path (from the encoders)",
        path,
    )?;
    draw_force_arrows(
        &mut chart,
        &f.run,
        f.traversal_s,
        0.2,
        |s| s.measured_n,
        RED_F,
        "force f of the wires (1 N = 1 cm)",
        path,
    )?;
    legend(&mut chart, SeriesLabelPosition::LowerMiddle, path)?;
    root.present().map_err(plot_error(path))?;
    Ok(())
}

fn draw_fig22(path: &Path, f: &Fig22) -> Result<(), ExperimentError> {
    let (x, z) = ((0.09, 0.41), (0.195, 0.315));
    let (w, top_h) = equal_aspect(x, z, 900);
    let bottom_h = 420;
    let root = BitMapBackend::new(path, (w, top_h + bottom_h)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error(path))?;
    let (top, bottom) = root.split_vertically(top_h);
    let s = &f.summary;
    let caption = format!(
        "Fig. 22 (twin): a surface with n in region C; F1 with |f_c| = {} N renders it \
         (reaction {:.2} N, V {:.2}), P1 without field does not ({:.2} N)",
        s.field.field_n, s.field.mean_reaction_n, s.field.mean_v_index, s.baseline.mean_reaction_n
    );
    let window = (0.0, f.timeline.end_s);
    {
        let mut chart = xz_chart(&top, &caption, x, z, path)?;
        draw_surface(&mut chart, &f.surface, x, z, "surface (n = +z)", path)?;
        draw_path(
            &mut chart,
            &f.baseline.run,
            window,
            GREY,
            "thimble path, P1 without field",
            path,
        )?;
        draw_path(
            &mut chart,
            &f.field.run,
            window,
            BLUE,
            "thimble path, F1, |f_c| = 2 N",
            path,
        )?;
        draw_force_arrows(
            &mut chart,
            &f.field.run,
            f.timeline.explore_s,
            0.5,
            |s| {
                if s.in_contact {
                    s.target_n
                } else {
                    Vec3::zeros()
                }
            },
            GREEN_F,
            "set-point f'_e = f_e + f_c, F1 (1 N = 1 cm)",
            path,
        )?;
        draw_force_arrows(
            &mut chart,
            &f.field.run,
            (f.timeline.free_s.0, f.timeline.explore_s.1),
            0.5,
            |s| s.measured_n,
            RED_F,
            "force f of the wires (measured), F1",
            path,
        )?;
        legend(&mut chart, SeriesLabelPosition::UpperRight, path)?;
    }
    let f_min = -2.6;
    let f_max = 2.2;
    let mut chart = ChartBuilder::on(&bottom)
        .caption(
            "z components of the forces on the thimble (contact from the touch to the lift-off)",
            ("sans-serif", 15),
        )
        .margin_left(10)
        .margin_right(20)
        .margin_top(5)
        .margin_bottom(10)
        .x_label_area_size(45)
        .y_label_area_size(65)
        .build_cartesian_2d(0.0..f.timeline.end_s, f_min..f_max)
        .map_err(plot_error(path))?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("force along z (= n), N")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_error(path))?;
    let series: [TimeSeries<'_>; 4] = [
        (
            &f.field.run,
            |s| s.desired_n.z,
            ORANGE,
            2,
            "f_e = K depth n (desired), F1",
        ),
        (
            &f.field.run,
            |s| s.target_n.z,
            GREEN_F,
            4,
            "f'_e = f_e + f_c (set-point), F1",
        ),
        (
            &f.field.run,
            |s| s.measured_n.z,
            RED_F,
            1,
            "f (measured), F1",
        ),
        (
            &f.baseline.run,
            |s| s.measured_n.z,
            GREY,
            1,
            "f (measured), P1 without field",
        ),
    ];
    for (run, value, colour, width, label) in series {
        // Separate segments: see `draw_path`.
        let points: Vec<(f64, f64)> = run
            .samples
            .iter()
            .map(|s| (s.time_s, value(s).clamp(f_min, f_max)))
            .collect();
        let style = colour.stroke_width(width);
        chart
            .draw_series(
                points
                    .windows(2)
                    .map(move |w| PathElement::new(vec![w[0], w[1]], style)),
            )
            .map_err(plot_error(path))?
            .label(label)
            .legend(move |(px, py)| {
                PathElement::new([(px, py), (px + 20, py)], colour.stroke_width(2))
            });
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, 0.0), (f.timeline.end_s, 0.0)],
            BLACK.stroke_width(1),
        ))
        .map_err(plot_error(path))?;
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(plot_error(path))?;
    root.present().map_err(plot_error(path))?;
    Ok(())
}

fn draw_fig23(path: &Path, f: &Fig23) -> Result<(), ExperimentError> {
    let (x, z) = ((-0.05, 0.50), (-0.04, 0.48));
    let size = equal_aspect(x, z, 760);
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error(path))?;
    let s = &f.summary;
    let caption = format!(
        "Fig. 23 (twin): one-wire device exploring a polygonal contour ({} of {} sides, within \
         {:.1} mm)",
        s.sides_explored,
        s.sides,
        s.path.max_distance_m * 1e3
    );
    let mut chart = xz_chart(&root, &caption, x, z, path)?;
    draw_surface(&mut chart, &f.contour, x, z, "contour", path)?;
    let guide = [f.device.guide_m()];
    let third = (f.traversal_s.1 - f.traversal_s.0) / 3.0;
    let positions: Vec<Vec3> = [f.traversal_s.0 + third, f.traversal_s.0 + 2.0 * third]
        .iter()
        .filter_map(|t| {
            f.run
                .window(*t, f.traversal_s.1)
                .next()
                .map(|s| s.position_m)
        })
        .collect();
    draw_wires(&mut chart, &guide, &positions, path)?;
    draw_guides(&mut chart, &guide, path)?;
    draw_path(
        &mut chart,
        &f.run,
        f.traversal_s,
        BLUE,
        "thimble path (x-z projection)",
        path,
    )?;
    let device = f.device;
    draw_force_arrows(
        &mut chart,
        &f.run,
        f.traversal_s,
        0.2,
        move |s| device.pull_direction(&s.position_m, 0) * s.tension_n[0],
        RED_F,
        "force of the wire (measured, 1 N = 1 cm)",
        path,
    )?;
    legend(&mut chart, SeriesLabelPosition::MiddleLeft, path)?;
    root.present().map_err(plot_error(path))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_control::SolidSide;

    #[test]
    fn temporary_files_keep_the_extension_beside_the_target() {
        let t = temporary_sibling(Path::new("/a/b/fig.png"));
        assert_eq!(t.parent(), Some(Path::new("/a/b")));
        assert!(t.to_string_lossy().ends_with("-fig.png"));
    }

    #[test]
    fn the_solid_of_an_open_profile_is_closed_on_its_side() {
        let p = Profile::open(
            &[Vec2::new(0.0, 0.2), Vec2::new(0.5, 0.2)],
            SolidSide::Right,
        )
        .unwrap();
        let poly = solid_polygon(&p, (0.0, 0.5), (0.0, 0.4));
        // Solid below the floor: every added corner lies at z <= 0.2.
        assert!(poly.iter().all(|&(_, z)| z <= 0.2 + 1e-12));
        assert!(poly.iter().any(|&(_, z)| z < 0.0));
    }
}
