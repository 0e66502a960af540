//! A still of what the Foxglove layout (`docs/foxglove-layout.json`) shows of a session at one
//! moment, drawn from the same quantities its topics carry: the 3-D scene (the relief, the
//! wires from their guides to the thimble coloured by tension, the forces f_e and f as arrows),
//! the last ten seconds of tensions, of the thimble's speed and the force, and the safety
//! state. For the documentation and for a report, where a live window cannot go.

use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::Arc;

use plotters::prelude::*;
use videt_control::safety::SafetyState;
use videt_runtime::cycle::CycleRecord;
use videt_runtime::telemetry::{LogItem, LogReader, RecordedSurface, SurfaceEntry};
use videt_viewers::topics::{surface_triangles, tension_colour, SceneSetup, FORCE_ARROW_M_PER_N};

use crate::plot_data::{norm, SafetyTimeline};
use crate::plotting::{draw_legend, line_mark, register_font, write_error, PlotError, TimeChart};

/// Seconds of history the plots show (the layout's plots follow the last 10 s).
const WINDOW_S: f64 = 10.0;

/// The 3-D panel's view: azimuth and elevation of an orthographic camera, radians.
const AZIMUTH: f64 = 0.55;
const ELEVATION: f64 = 0.45;

const BACKGROUND: RGBColor = RGBColor(21, 21, 26);
const PANEL: RGBColor = RGBColor(30, 30, 36);
const TEXT: RGBColor = RGBColor(220, 220, 225);
const WIRE_COLOURS: [RGBColor; 3] = [
    RGBColor(78, 152, 226),
    RGBColor(245, 119, 77),
    RGBColor(98, 195, 112),
];

/// Chooses, as the periods come, the one the still shows: the one at `at_s` seconds into the
/// session, or else the moment in contact with the largest desired force (the surface pressed
/// hardest), or without contact the largest rendered force.
struct MomentChooser {
    at_s: Option<f64>,
    t0_s: Option<f64>,
    periods: usize,
    at: Option<usize>,
    /// The largest desired force in contact and the largest rendered force, with their
    /// periods (the later of equals).
    pressed: Option<(f64, usize)>,
    rendered: Option<(f64, usize)>,
}

impl MomentChooser {
    fn new(at_s: Option<f64>) -> MomentChooser {
        MomentChooser {
            at_s,
            t0_s: None,
            periods: 0,
            at: None,
            pressed: None,
            rendered: None,
        }
    }

    fn add(&mut self, r: &CycleRecord) {
        let i = self.periods;
        self.periods += 1;
        let t = r.time.as_secs_f64();
        let t0 = *self.t0_s.get_or_insert(t);
        if self.at.is_none() && self.at_s.is_some_and(|at| t - t0 >= at) {
            self.at = Some(i);
        }
        let larger = |best: Option<(f64, usize)>, f: f64| best.is_none_or(|(b, _)| f >= b);
        let desired = norm(r.desired_force_n);
        if r.in_contact && larger(self.pressed, desired) {
            self.pressed = Some((desired, i));
        }
        let rendered = norm(r.rendered_force_n);
        if larger(self.rendered, rendered) {
            self.rendered = Some((rendered, i));
        }
    }

    /// The period chosen (`None`: no period).
    fn chosen(&self) -> Option<usize> {
        let last = self.periods.checked_sub(1)?;
        Some(match self.at_s {
            Some(_) => self.at.unwrap_or(last),
            None => self.pressed.or(self.rendered).map_or(0, |(_, i)| i),
        })
    }
}

/// The moment the still shows, read from the log: the period, the ten seconds before it, the
/// calibration in force and the surface it rendered.
struct Moment {
    window: Vec<CycleRecord>,
    calibration: Option<videt_runtime::telemetry::CalibrationInForce>,
    surface: Option<Arc<RecordedSurface>>,
}

impl Moment {
    /// Read `logfile` up to its period number `now` (counted from 0).
    fn read(logfile: &Path, now: usize) -> Result<Moment, PlotError> {
        let mut window = VecDeque::new();
        let mut calibration = None;
        // Recorded surfaces not older than the newest one a period has rendered.
        let mut surfaces: BTreeMap<u64, Arc<RecordedSurface>> = BTreeMap::new();
        let mut periods = 0;
        for item in open_log(logfile)? {
            match item {
                LogItem::Calibration { calibration: c, .. } => calibration = Some(c),
                LogItem::Surface(version, SurfaceEntry::Recorded(s)) => {
                    surfaces.insert(version, s);
                }
                LogItem::Period(r) => {
                    let t = r.time.as_secs_f64();
                    while window
                        .front()
                        .is_some_and(|f: &CycleRecord| f.time.as_secs_f64() < t - WINDOW_S)
                    {
                        window.pop_front();
                    }
                    // The newest recorded surface at or before the one rendered is kept; the
                    // older ones are not shown again.
                    let shown = surfaces.range(..=r.surface_version).next_back();
                    if let Some(&shown) = shown.map(|(v, _)| v) {
                        if surfaces.first_key_value().is_some_and(|(v, _)| *v < shown) {
                            surfaces = surfaces.split_off(&shown);
                        }
                    }
                    window.push_back(r);
                    if periods == now {
                        let surface = surfaces
                            .range(..=r.surface_version)
                            .next_back()
                            .map(|(_, s)| s.clone());
                        return Ok(Moment {
                            window: window.into(),
                            calibration,
                            surface,
                        });
                    }
                    periods += 1;
                }
                _ => {}
            }
        }
        Err(format!("{}: the log changed while it was read", logfile.display()).into())
    }
}

/// `logfile` opened for reading, or an error naming it.
fn open_log(logfile: &Path) -> Result<LogReader<std::io::BufReader<std::fs::File>>, PlotError> {
    LogReader::open(logfile).map_err(|e| format!("{}: {e}", logfile.display()).into())
}

/// Orthographic projection of the rig's frame: x to the right, the frame's y up, z (away
/// from the frame, towards the scene) into the picture, turned by [`AZIMUTH`] and
/// [`ELEVATION`]. Returns (right, up).
fn project(p: [f64; 3]) -> (f64, f64) {
    let (sa, ca) = AZIMUTH.sin_cos();
    let (se, ce) = ELEVATION.sin_cos();
    let x = ca * p[0] + sa * p[2];
    let depth = -sa * p[0] + ca * p[2];
    let y = ce * p[1] + se * depth;
    (x, y)
}

fn colour_of(c: &foxglove::schemas::Color) -> RGBColor {
    let byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    RGBColor(byte(c.r), byte(c.g), byte(c.b))
}

/// Write the still of the session log `logfile` (recorded with `config`) at `at_s` seconds
/// into the session (default: the moment of the largest desired force in contact) to `path`,
/// 1600 × 900 pixels; returns the time shown, seconds into the session. The log is read twice
/// as a stream: to choose the moment, then up to it.
pub fn write_view_figure(
    path: &Path,
    logfile: &Path,
    config: &videt_config::Config,
    at_s: Option<f64>,
) -> Result<f64, PlotError> {
    let mut chooser = MomentChooser::new(at_s);
    let mut safety = SafetyTimeline::default();
    for item in open_log(logfile)? {
        if let LogItem::Period(r) = item {
            chooser.add(&r);
            safety.add(&r);
        }
    }
    let Some(now) = chooser.chosen() else {
        return Err("the log has no period to draw".into());
    };
    let moment = Moment::read(logfile, now)?;
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(write_error(dir))?;
    }
    register_font();
    let e = write_error(path);
    let window = &moment.window;
    let r = &window[window.len() - 1];
    let setup = &SceneSetup::new(config, moment.calibration.as_ref());
    let t0 = safety.t0_s.unwrap_or_default();
    let t_now = r.time.as_secs_f64() - t0;
    let root = BitMapBackend::new(path, (1600, 900)).into_drawing_area();
    root.fill(&BACKGROUND).map_err(e)?;
    let (left, right) = root.split_horizontally(880);
    let (scene_area, state_area) = left.split_vertically(770);
    scene_panel(&scene_area, moment.surface.as_deref(), setup, r, path)?;
    state_panel(&state_area, &safety, r, path)?;
    let plots = right.split_evenly((3, 1));
    tension_plot(&plots[0], window, t0, setup, path)?;
    motion_plot(&plots[1], window, t0, path)?;
    timing_plot(&plots[2], window, t0, path)?;
    root.present().map_err(write_error(path))?;
    Ok(t_now)
}

fn scene_panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    surface: Option<&RecordedSurface>,
    setup: &SceneSetup,
    r: &CycleRecord,
    path: &Path,
) -> Result<(), PlotError> {
    let e = |x| write_error(path)(x);
    area.fill(&PANEL).map_err(e)?;
    let wires = setup.wires.min(setup.guides_m.len()).min(3);
    // The view spans the guides, the thimble and the surface.
    let mut points: Vec<[f64; 3]> = setup.guides_m[..wires].to_vec();
    points.push(r.position_m);
    // The surface as the /scene/relief topic draws it.
    let triangles: Vec<[[f64; 3]; 3]> = surface.map_or_else(Vec::new, |s| {
        let mesh = surface_triangles(s);
        let corner = |i: u32| {
            let p = &mesh.points[i as usize];
            [p.x, p.y, p.z]
        };
        mesh.indices
            .chunks_exact(3)
            .map(|t| [corner(t[0]), corner(t[1]), corner(t[2])])
            .collect()
    });
    points.extend(triangles.iter().flatten().copied());
    let projected: Vec<(f64, f64)> = points.iter().map(|p| project(*p)).collect();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in &projected {
        x0 = x0.min(*x);
        x1 = x1.max(*x);
        y0 = y0.min(*y);
        y1 = y1.max(*y);
    }
    // Square scale with a margin, the panel's aspect kept.
    let (w_px, h_px) = area.dim_in_pixel();
    let aspect = f64::from(w_px) / f64::from(h_px);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let half_h = ((y1 - y0) / 2.0).max((x1 - x0) / 2.0 / aspect) * 1.15 + 1e-3;
    let half_w = half_h * aspect;
    let mut chart = ChartBuilder::on(area)
        .caption(
            format!(
                "3D — {} (frame \"rig\"), surface version {}",
                setup.device, r.surface_version
            ),
            ("sans-serif", 16).into_font().color(&TEXT),
        )
        .margin(10)
        .build_cartesian_2d((cx - half_w)..(cx + half_w), (cy - half_h)..(cy + half_h))
        .map_err(e)?;
    // The frame plane's grid, 10 cm.
    let grid = RGBColor(58, 58, 68);
    for k in -3..=8 {
        let s = f64::from(k) * 0.1;
        for (a, b) in [
            ([s, -0.3, 0.0], [s, 0.8, 0.0]),
            ([-0.3, s, 0.0], [0.8, s, 0.0]),
        ] {
            chart
                .draw_series(LineSeries::new(
                    [project(a), project(b)],
                    grid.stroke_width(1),
                ))
                .map_err(e)?;
        }
    }
    // The relief, shaded by depth (nearer the frame: lighter), back to front.
    let (z_lo, z_hi) = triangles
        .iter()
        .flatten()
        .fold((f64::MAX, f64::MIN), |(lo, hi), p| {
            (lo.min(p[2]), hi.max(p[2]))
        });
    let mut order: Vec<usize> = (0..triangles.len()).collect();
    let depth_of = |t: &[[f64; 3]; 3]| {
        let (sa, ca) = AZIMUTH.sin_cos();
        t.iter().map(|p| -sa * p[0] + ca * p[2]).sum::<f64>()
    };
    order.sort_by(|&a, &b| depth_of(&triangles[b]).total_cmp(&depth_of(&triangles[a])));
    for i in order {
        let t = &triangles[i];
        let z = t.iter().map(|p| p[2]).sum::<f64>() / 3.0;
        let shade = 1.0 - 0.6 * ((z - z_lo) / (z_hi - z_lo).max(1e-9));
        let fill = RGBColor(
            (70.0 + 110.0 * shade) as u8,
            (80.0 + 100.0 * shade) as u8,
            (95.0 + 90.0 * shade) as u8,
        );
        let poly: Vec<(f64, f64)> = t.iter().map(|p| project(*p)).collect();
        chart
            .draw_series(std::iter::once(Polygon::new(poly.clone(), fill.filled())))
            .map_err(e)?;
        let mut edge = poly.clone();
        edge.push(poly[0]);
        chart
            .draw_series(LineSeries::new(edge, BACKGROUND.mix(0.5).stroke_width(1)))
            .map_err(e)?;
    }
    // The wires, coloured by measured tension as the /scene/wires topic colours them.
    let thimble = project(r.position_m);
    for w in 0..wires {
        let c = colour_of(&tension_colour(
            r.tension_measured_n[w],
            setup.tension_range_n,
        ));
        chart
            .draw_series(LineSeries::new(
                [project(setup.guides_m[w]), thimble],
                c.stroke_width(3),
            ))
            .map_err(e)?
            .label(format!("wire {w}: {:.2} N", r.tension_measured_n[w]))
            .legend(line_mark(c.stroke_width(3)));
        chart
            .draw_series(std::iter::once(Circle::new(
                project(setup.guides_m[w]),
                6,
                RGBColor(150, 150, 150).filled(),
            )))
            .map_err(e)?;
    }
    // The forces at the thimble, as the /scene/forces arrows (1 cm per N).
    for (force, colour, name) in [
        (r.desired_force_n, RGBColor(51, 204, 77), "f_e (desired)"),
        (r.rendered_force_n, RGBColor(255, 115, 26), "f (rendered)"),
    ] {
        let tip = core::array::from_fn(|k| r.position_m[k] + FORCE_ARROW_M_PER_N * force[k]);
        chart
            .draw_series(LineSeries::new(
                [thimble, project(tip)],
                colour.stroke_width(4),
            ))
            .map_err(e)?
            .label(format!("{name}: {:.2} N", norm(force)))
            .legend(line_mark(colour.stroke_width(4)));
        chart
            .draw_series(std::iter::once(Circle::new(
                project(tip),
                4,
                colour.filled(),
            )))
            .map_err(e)?;
    }
    chart
        .draw_series(std::iter::once(Circle::new(
            thimble,
            9,
            RGBColor(255, 217, 51).filled(),
        )))
        .map_err(e)?
        .label(format!(
            "thimble ({:+.3}, {:+.3}, {:+.3}) m",
            r.position_m[0], r.position_m[1], r.position_m[2]
        ))
        .legend(|(x, y)| Circle::new((x + 10, y), 6, RGBColor(255, 217, 51).filled()));
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, path)?;
    Ok(())
}

fn state_panel(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    safety: &SafetyTimeline,
    r: &CycleRecord,
    path: &Path,
) -> Result<(), PlotError> {
    let e = |x| write_error(path)(x);
    area.fill(&PANEL).map_err(e)?;
    let t0 = safety.t0_s.unwrap_or_default();
    let state = match r.safety.reason() {
        Some(reason) => format!("{} ({})", r.safety.as_str(), reason.as_str()),
        None => r.safety.as_str().to_string(),
    };
    let colour = state_colour(r.safety);
    let font = ("sans-serif", 16).into_font().color(&TEXT);
    area.draw(&Text::new(
        format!(
            "State transitions — /safety   t = {:.3} s   period {}",
            r.time.as_secs_f64() - t0,
            r.cycle
        ),
        (12, 10),
        font.clone(),
    ))
    .map_err(e)?;
    // A band per state over the session, as the state-transitions panel draws it.
    let (w_px, _) = area.dim_in_pixel();
    let t_end = safety.t_end_s - t0;
    let span = t_end.max(1e-6);
    let x_at = |t: f64| 12 + (t / span * f64::from(w_px - 24)) as i32;
    let x_of = |r: &CycleRecord| x_at(r.time.as_secs_f64() - t0);
    // The session opens in the state of its first period (`Normal` unless a transition is at
    // its start).
    let transitions = &safety.transitions.kept;
    let opens_normal = transitions.first().is_none_or(|t| t.0 > 0.0);
    let starts: Vec<(f64, SafetyState)> = opens_normal
        .then_some((0.0, SafetyState::Normal))
        .into_iter()
        .chain(transitions.iter().copied())
        .collect();
    for (i, &(start, state)) in starts.iter().enumerate() {
        let end = starts.get(i + 1).map_or(t_end, |b| b.0);
        area.draw(&Rectangle::new(
            [(x_at(start), 40), (x_at(end).max(x_at(start) + 1), 62)],
            state_colour(state).filled(),
        ))
        .map_err(e)?;
    }
    area.draw(&Rectangle::new(
        [(x_of(r) - 1, 36), (x_of(r) + 1, 66)],
        WHITE.filled(),
    ))
    .map_err(e)?;
    area.draw(&Text::new(
        format!(
            "safety: {state}   surface {}   released wire {}",
            if r.surface_stale { "stale" } else { "fresh" },
            if r.released_wire < 0 {
                "none".to_string()
            } else {
                r.released_wire.to_string()
            }
        ),
        (12, 76),
        ("sans-serif", 16).into_font().color(&colour),
    ))
    .map_err(e)?;
    Ok(())
}

fn state_colour(state: SafetyState) -> RGBColor {
    match state {
        SafetyState::Normal => RGBColor(98, 195, 112),
        SafetyState::MinimumTension(_) => RGBColor(230, 190, 60),
        SafetyState::PowerOff(_) => RGBColor(230, 80, 80),
    }
}

fn dark_chart<'a>(
    area: &DrawingArea<BitMapBackend<'a>, plotters::coord::Shift>,
    caption: &str,
    x: core::ops::Range<f64>,
    y: core::ops::Range<f64>,
    y_desc: &str,
    path: &Path,
) -> Result<TimeChart<'a>, PlotError> {
    area.fill(&PANEL).map_err(write_error(path))?;
    let mut chart = ChartBuilder::on(area)
        .caption(caption, ("sans-serif", 16).into_font().color(&TEXT))
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(50)
        .build_cartesian_2d(x, y)
        .map_err(write_error(path))?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc(y_desc)
        .axis_style(TEXT.mix(0.6))
        .bold_line_style(RGBColor(58, 58, 68))
        .light_line_style(RGBColor(40, 40, 48))
        .label_style(("sans-serif", 12).into_font().color(&TEXT))
        .axis_desc_style(("sans-serif", 13).into_font().color(&TEXT))
        .draw()
        .map_err(write_error(path))?;
    Ok(chart)
}

fn time_range(window: &[CycleRecord], t0: f64) -> core::ops::Range<f64> {
    let end = window[window.len() - 1].time.as_secs_f64() - t0;
    (end - WINDOW_S).max(0.0)..end.max(1e-3)
}

fn tension_plot(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    window: &[CycleRecord],
    t0: f64,
    setup: &SceneSetup,
    path: &Path,
) -> Result<(), PlotError> {
    let hi = setup.tension_range_n[1] * 1.07;
    let mut chart = dark_chart(
        area,
        "Wire tension, measured and set-point — /tension",
        time_range(window, t0),
        0.0..hi,
        "N",
        path,
    )?;
    let wires = setup.wires.min(3);
    for w in 0..wires {
        let c = WIRE_COLOURS[w];
        let t = |r: &CycleRecord| r.time.as_secs_f64() - t0;
        chart
            .draw_series(LineSeries::new(
                window.iter().map(|r| (t(r), r.tension_setpoint_n[w])),
                c.mix(0.55).stroke_width(1),
            ))
            .map_err(write_error(path))?;
        chart
            .draw_series(LineSeries::new(
                window.iter().map(|r| (t(r), r.tension_measured_n[w])),
                c.stroke_width(2),
            ))
            .map_err(write_error(path))?
            .label(format!("measured_n[{w}] (thin: setpoint_n[{w}])"))
            .legend(line_mark(c.stroke_width(2)));
    }
    draw_legend(&mut chart, SeriesLabelPosition::UpperLeft, path)
}

fn motion_plot(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    window: &[CycleRecord],
    t0: f64,
    path: &Path,
) -> Result<(), PlotError> {
    let f_max = window
        .iter()
        .map(|r| norm(r.rendered_force_n).max(norm(r.desired_force_n)))
        .fold(0.0, f64::max);
    let v_max = window
        .iter()
        .map(|r| norm(r.velocity_m_s))
        .fold(0.0, f64::max);
    // Speed in cm/s beside force in N: one axis, both readable.
    let hi = (f_max.max(v_max * 100.0) * 1.15).max(0.5);
    let mut chart = dark_chart(
        area,
        "Thimble speed V and contact force — /tension",
        time_range(window, t0),
        0.0..hi,
        "N, cm/s",
        path,
    )?;
    let speed_cm_s = |r: &CycleRecord| 100.0 * norm(r.velocity_m_s);
    let rendered = |r: &CycleRecord| norm(r.rendered_force_n);
    let desired = |r: &CycleRecord| norm(r.desired_force_n);
    let series: [(&str, RGBColor, Quantity); 3] = [
        (
            "speed_m_s (× 100, cm/s)",
            RGBColor(224, 195, 65),
            speed_cm_s,
        ),
        (
            "rendered_force_norm_n |f|",
            RGBColor(255, 115, 26),
            rendered,
        ),
        ("desired_force_norm_n |f_e|", RGBColor(51, 204, 77), desired),
    ];
    draw_quantities(&mut chart, window, t0, &series, 2, f64::INFINITY, path)
}

/// A quantity of a period's record.
type Quantity = fn(&CycleRecord) -> f64;

/// One labelled line per quantity over `window` (time from `t0`), `width` pixels wide, values
/// clipped at `clip`, and the legend.
fn draw_quantities(
    chart: &mut TimeChart<'_>,
    window: &[CycleRecord],
    t0: f64,
    series: &[(&str, RGBColor, Quantity)],
    width: u32,
    clip: f64,
    path: &Path,
) -> Result<(), PlotError> {
    for &(name, c, value) in series {
        chart
            .draw_series(LineSeries::new(
                window
                    .iter()
                    .map(|r| (r.time.as_secs_f64() - t0, value(r).min(clip))),
                c.stroke_width(width),
            ))
            .map_err(write_error(path))?
            .label(name)
            .legend(line_mark(c.stroke_width(2)));
    }
    draw_legend(chart, SeriesLabelPosition::UpperLeft, path)
}

fn timing_plot(
    area: &DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>,
    window: &[CycleRecord],
    t0: f64,
    path: &Path,
) -> Result<(), PlotError> {
    let mut values: Vec<f64> = window
        .iter()
        .flat_map(|r| [r.wake_latency_ns as f64, r.compute_ns as f64])
        .collect();
    values.sort_by(f64::total_cmp);
    // The scale shows 99.9 % of the values; the rare peak above is clipped, not hidden.
    let p999 = values[((values.len() - 1) as f64 * 0.999) as usize] * 1e-3;
    let hi = (p999 * 1.2).max(10.0);
    let mut chart = dark_chart(
        area,
        "Control period: wake-up latency and compute — /timing",
        time_range(window, t0),
        0.0..hi,
        "µs",
        path,
    )?;
    let wake_us = |r: &CycleRecord| r.wake_latency_ns as f64 * 1e-3;
    let compute_us = |r: &CycleRecord| r.compute_ns as f64 * 1e-3;
    let series: [(&str, RGBColor, Quantity); 2] = [
        ("wake_latency_us", WIRE_COLOURS[0], wake_us),
        ("compute_us", WIRE_COLOURS[1], compute_us),
    ];
    draw_quantities(&mut chart, window, t0, &series, 1, hi, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_still_shows_the_moment_of_the_largest_force_unless_asked_for_another() {
        let mut records = vec![CycleRecord::default(); 5];
        for (i, r) in records.iter_mut().enumerate() {
            r.time = videt_hal::MonoTime(1_000_000_000 + i as u64 * 1_000_000_000);
        }
        let chosen_period = |records: &[CycleRecord], at: Option<f64>| {
            let mut chooser = MomentChooser::new(at);
            records.iter().for_each(|r| chooser.add(r));
            chooser.chosen().unwrap()
        };
        assert_eq!(MomentChooser::new(None).chosen(), None);
        records[3].rendered_force_n = [0.0, 0.0, 2.5];
        assert_eq!(chosen_period(&records, None), 3);
        // In contact, the desired force decides (a transient of the rendered one elsewhere
        // does not).
        records[1].in_contact = true;
        records[1].desired_force_n = [0.0, 0.0, 1.0];
        assert_eq!(chosen_period(&records, None), 1);
        assert_eq!(chosen_period(&records, Some(1.5)), 2);
        assert_eq!(chosen_period(&records, Some(99.0)), 4);
    }

    #[test]
    fn the_projection_keeps_the_frame_planes_vertical_upright() {
        // Up in the frame plane is up in the picture; a point further from the frame lies
        // higher (seen from above) and to the right (seen from the right).
        let (_, y0) = project([0.0, 0.0, 0.0]);
        let (_, y1) = project([0.0, 0.1, 0.0]);
        assert!(y1 > y0);
        let (x2, y2) = project([0.0, 0.0, 0.3]);
        assert!(x2 > 0.0 && y2 > y0);
    }
}
