//! `videt analyze`: the designer's tool (paper Fig. 6, section 6). For a rig geometry and a
//! thimble position it reports how well each control algorithm renders contact forces: the index
//! V (eq. 8) over every direction of the contact force and the isotropic force limit (the radius
//! of `S_f`, Fig. 16c), and draws the V polar plot (Figs. 19-21) and a heat map of the isotropic
//! force limit over the workspace.
//!
//! Conventions:
//! - 3 wires (default): `--guide X,Y` three times, metres, in the `z = 0` plane; `--at X,Y,Z`.
//! - `--planar`: the two-wire device of the paper's experiments, moving in the x-z plane. Guides
//!   lie on the x axis: `--guide X,0` (or just `--guide X`; a nonzero Y is an error). `--at X,Z`.
//! - Without `--guide` the reference rigs are used: planar, the paper's prototype (guides at
//!   x = 0 and 0.52 m); 3 wires, the backpack frame's triangle (0,0), (0.37,0), (0.185,0.30).
//! - The field `f_c` (`--fc`) points along `-z` (towards the guides) for P1, P2 and F1, and along
//!   the bisector of the wires for F2 and QP. V is measured against `f'_e = f_e + f_c` (eq. 8).
//! - Directions: planar, every 1 degree in the x-z plane from +x towards +z; 3 wires, an
//!   equirectangular grid every 5 degrees (azimuth in the x-y plane from +x towards +y,
//!   elevation from the x-y plane towards +z; the poles once), 2522 directions.
//! - A target `f_e + f_c` of zero (the contact force cancelling the field) has V = 1 by
//!   convention (nothing asked, nothing missed).
//! - The analysed workspace: at least 1 cm in front of the guide plane (z >= 0.01 m) and every
//!   wire at most 1.5 m long.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Args;
use nalgebra::Vector2;
use serde::Serialize;
use videt_control::analysis::{
    evaluate_direction, isotropic_limit_at, setup_field, sweep_planar, sweep_spatial,
    AnalysisSetup, SummaryBuilder, SweepSummary, WireDevice,
};
use videt_control::{Algorithm, ForceLimits, Rig3, RigPlanar, Vec3};

use super::ToolResult;

/// Smallest distance of the analysed point in front of the guide plane, metres.
pub const MIN_HEIGHT_M: f64 = 0.01;
/// Longest wire of the analysed workspace, metres.
pub const MAX_WIRE_LENGTH_M: f64 = 1.5;

/// Arguments of `videt analyze`.
#[derive(Debug, Clone, Args)]
pub struct AnalyzeArgs {
    /// Planar two-wire device (x-z plane) instead of the three-wire device.
    #[arg(long)]
    pub planar: bool,
    /// A guide point "X,Y" in metres (z = 0); three of them, or two with --planar ("X,0").
    /// Default: the reference rig.
    #[arg(long = "guide", value_name = "X,Y", allow_hyphen_values = true)]
    pub guides: Vec<String>,
    /// Thimble position: "X,Z" with --planar, "X,Y,Z" otherwise, metres.
    /// Default: planar 0.26,0.26 (the paper's); 3 wires 0.3 m above the guides' centroid.
    #[arg(long, value_name = "POINT", allow_hyphen_values = true)]
    pub at: Option<String>,
    /// Control algorithm: P1, P2, F1, F2 or QP.
    #[arg(long, default_value = "P1")]
    pub algorithm: String,
    /// Magnitude of the force field f_c, newtons.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub fc: f64,
    /// Minimum wire tension, newtons (the paper's analysis: 0).
    #[arg(long = "t-min", default_value_t = 0.0, allow_hyphen_values = true)]
    pub t_min: f64,
    /// Maximum wire tension, newtons (the device: 15).
    #[arg(long = "t-max", default_value_t = 15.0, allow_hyphen_values = true)]
    pub t_max: f64,
    /// Magnitude |f_e| of the contact force swept over directions, newtons.
    #[arg(long, default_value_t = 1.0, allow_hyphen_values = true)]
    pub force: f64,
    /// Print the result as JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Directory for the plots, created if missing: planar v_polar.png (V over direction for
    /// |f_c| from 0 to --fc) and v_compare.png (every algorithm); 3 wires v_sphere.png (V over
    /// azimuth and elevation); both isotropic_heatmap.png (isotropic force limit over the
    /// workspace: x-z plane, or the x-y slice at the thimble's height).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

/// A validated analysis request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// Planar two-wire device at `[x, z]`.
    Planar {
        /// The rig.
        rig: RigPlanar,
        /// Position `[x, z]`, metres.
        at_m: Vector2<f64>,
    },
    /// Three-wire device.
    Spatial {
        /// The rig.
        rig: Rig3,
        /// Position, metres.
        at_m: Vec3,
    },
}

/// A bad command line, with the flag it concerns.
#[derive(Debug, Clone, PartialEq)]
pub struct ArgError(pub String);

impl std::fmt::Display for ArgError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ArgError {}

fn err<T>(message: String) -> Result<T, ArgError> {
    Err(ArgError(message))
}

/// Parse "a,b[,c]" into exactly `count` finite numbers.
fn parse_numbers(flag: &str, text: &str, count: usize) -> Result<Vec<f64>, ArgError> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != count {
        return err(format!(
            "{flag} {text:?}: expected {count} comma-separated numbers, got {}",
            parts.len()
        ));
    }
    parts
        .iter()
        .map(|p| match p.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => err(format!("{flag} {text:?}: {p:?} is not a finite number")),
        })
        .collect()
}

/// Validate everything but the algorithm-independent numbers into a rig and a point.
pub fn parse_request(args: &AnalyzeArgs) -> Result<Request, ArgError> {
    if args.planar {
        let guides_x = match args.guides.len() {
            0 => [0.0, 0.52],
            2 => {
                let mut xs = [0.0; 2];
                for (x, text) in xs.iter_mut().zip(&args.guides) {
                    let v = if text.contains(',') {
                        parse_numbers("--guide", text, 2)?
                    } else {
                        parse_numbers("--guide", text, 1)?
                    };
                    if v.len() == 2 && v[1] != 0.0 {
                        return err(format!(
                            "--guide {text:?}: planar guides lie on the x axis, Y must be 0"
                        ));
                    }
                    *x = v[0];
                }
                xs
            }
            n => {
                return err(format!(
                    "--planar needs exactly 2 --guide points (or none for the paper's prototype), got {n}"
                ))
            }
        };
        let rig = RigPlanar::new(guides_x)
            .map_err(|e| ArgError(format!("--guide: rejected rig: {e}")))?;
        let at = match &args.at {
            Some(text) => {
                let v = parse_numbers("--at", text, 2)?;
                Vector2::new(v[0], v[1])
            }
            None => Vector2::new(0.26, 0.26),
        };
        check_planar_point(&rig, &at).map_err(|e| ArgError(format!("--at: {e}")))?;
        Ok(Request::Planar { rig, at_m: at })
    } else {
        let guides = match args.guides.len() {
            0 => [
                Vec3::zeros(),
                Vec3::new(0.37, 0.0, 0.0),
                Vec3::new(0.185, 0.30, 0.0),
            ],
            3 => {
                let mut g = [Vec3::zeros(); 3];
                for (gi, text) in g.iter_mut().zip(&args.guides) {
                    let v = parse_numbers("--guide", text, 2)?;
                    *gi = Vec3::new(v[0], v[1], 0.0);
                }
                g
            }
            n => {
                return err(format!(
                    "a three-wire rig needs exactly 3 --guide points (or none for the reference rig), got {n}; use --planar for the two-wire device"
                ))
            }
        };
        let rig = Rig3::new(guides).map_err(|e| ArgError(format!("--guide: rejected rig: {e}")))?;
        let at = match &args.at {
            Some(text) => {
                let v = parse_numbers("--at", text, 3)?;
                Vec3::new(v[0], v[1], v[2])
            }
            None => (guides[0] + guides[1] + guides[2]) / 3.0 + Vec3::new(0.0, 0.0, 0.3),
        };
        check_spatial_point(&rig, &at).map_err(|e| ArgError(format!("--at: {e}")))?;
        Ok(Request::Spatial { rig, at_m: at })
    }
}

/// Why a point is outside the analysed workspace, or `Ok`.
pub fn check_planar_point(rig: &RigPlanar, at: &Vector2<f64>) -> Result<(), String> {
    check_point(at.y, &rig.inverse(at), rig.wire_map(at).is_some())
}

/// Why a point is outside the analysed workspace, or `Ok`.
pub fn check_spatial_point(rig: &Rig3, at: &Vec3) -> Result<(), String> {
    check_point(at.z, &rig.inverse(at), rig.wire_map(at).is_some())
}

fn check_point(height_m: f64, lengths_m: &[f64], regular: bool) -> Result<(), String> {
    if height_m < MIN_HEIGHT_M {
        return Err(format!(
            "the thimble must be in front of the guide plane: z = {height_m} m, need z >= {MIN_HEIGHT_M} m"
        ));
    }
    if let Some(l) = lengths_m.iter().find(|&&l| l > MAX_WIRE_LENGTH_M) {
        return Err(format!(
            "outside the workspace: a wire would be {l:.3} m long, at most {MAX_WIRE_LENGTH_M} m"
        ));
    }
    if !regular {
        return Err("the wires are (nearly) aligned there: singular point".into());
    }
    Ok(())
}

/// Validate the numeric flags into an analysis setup.
pub fn parse_setup(args: &AnalyzeArgs) -> Result<AnalysisSetup, ArgError> {
    let algorithm = Algorithm::from_name(&args.algorithm).ok_or_else(|| {
        ArgError(format!(
            "--algorithm {:?}: unknown, use one of {}",
            args.algorithm,
            videt_control::distribution::ALGORITHM_NAMES.join(", ")
        ))
    })?;
    let limits = ForceLimits::new(args.t_min, args.t_max)
        .map_err(|e| ArgError(format!("--t-min/--t-max: {e}")))?;
    if !(args.fc.is_finite() && args.fc >= 0.0) {
        return err(format!("--fc {}: need a finite value >= 0 N", args.fc));
    }
    if !(args.force.is_finite() && args.force > 0.0) {
        return err(format!("--force {}: need a finite value > 0 N", args.force));
    }
    Ok(AnalysisSetup {
        algorithm,
        field_n: args.fc,
        limits,
        force_n: args.force,
    })
}

/// One direction of the JSON output.
#[derive(Debug, Serialize)]
#[serde(untagged)]
enum VEntry {
    Planar {
        direction_deg: f64,
        v: f64,
    },
    Spatial {
        azimuth_deg: f64,
        elevation_deg: f64,
        v: f64,
    },
}

/// The JSON output.
#[derive(Debug, Serialize)]
struct Report {
    algorithm: &'static str,
    fc_n: f64,
    position_m: Vec<f64>,
    isotropic_force_n: f64,
    v_index: Vec<VEntry>,
}

/// Everything computed for one algorithm at the point.
struct Analysis {
    report: Report,
    summary: SweepSummary,
    field_n: Vec<f64>,
}

fn analyse(request: &Request, setup: &AnalysisSetup) -> Analysis {
    let mut summary = SummaryBuilder::default();
    let mut entries = Vec::new();
    let (position_m, isotropic, field_n) = match request {
        Request::Planar { rig, at_m } => {
            let map = rig.wire_map(at_m).expect("checked regular");
            sweep_planar(&map, setup, |deg, s| {
                summary.add(s);
                entries.push(VEntry::Planar {
                    direction_deg: deg,
                    v: s.v,
                });
            });
            let fc = setup_field(&map, setup);
            (
                vec![at_m.x, at_m.y],
                isotropic_limit_at(rig, at_m, setup).unwrap_or(0.0),
                vec![fc.x, fc.y],
            )
        }
        Request::Spatial { rig, at_m } => {
            let map = rig.wire_map(at_m).expect("checked regular");
            sweep_spatial(&map, setup, |az, el, s| {
                summary.add(s);
                entries.push(VEntry::Spatial {
                    azimuth_deg: az,
                    elevation_deg: el,
                    v: s.v,
                });
            });
            let fc = setup_field(&map, setup);
            (
                vec![at_m.x, at_m.y, at_m.z],
                isotropic_limit_at(rig, at_m, setup).unwrap_or(0.0),
                vec![fc.x, fc.y, fc.z],
            )
        }
    };
    Analysis {
        report: Report {
            algorithm: setup.algorithm.name(),
            fc_n: setup.field_n,
            position_m,
            isotropic_force_n: isotropic,
            v_index: entries,
        },
        summary: summary.finish(),
        field_n,
    }
}

/// Run `videt analyze`.
pub fn run(args: &AnalyzeArgs) -> ToolResult {
    let request = parse_request(args)?;
    let setup = parse_setup(args)?;
    let main = analyse(&request, &setup);
    let text = if args.json {
        let mut json = serde_json::to_string(&main.report)?;
        json.push('\n');
        json
    } else {
        text_report(&request, &setup, &main)
    };
    print_stdout(&text)?;
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir)
            .map_err(|e| format!("--out {}: cannot create: {e}", dir.display()))?;
        let written = plots::write_all(dir, &request, &setup)?;
        if !args.json {
            for path in written {
                print_stdout(&format!("wrote {}\n", path.display()))?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Write to stdout; a closed pipe (`videt analyze ... | head`) is not an error.
fn print_stdout(text: &str) -> Result<(), std::io::Error> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => other,
    }
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
    format!("[{}]", parts.join(", "))
}

fn text_report(request: &Request, setup: &AnalysisSetup, main: &Analysis) -> String {
    let mut s = String::new();
    let (rig_text, directions) = match request {
        Request::Planar { rig, .. } => (
            format!(
                "planar 2-wire, guides at x = {} m and {} m (x-z plane)",
                rig.guides_x_m()[0],
                rig.guides_x_m()[1]
            ),
            "360 directions in the x-z plane",
        ),
        Request::Spatial { rig, .. } => {
            let g = rig.guides_m();
            (
                format!(
                    "3-wire, guides at ({}, {}), ({}, {}), ({}, {}) m",
                    g[0].x, g[0].y, g[1].x, g[1].y, g[2].x, g[2].y
                ),
                "2522 directions over the sphere",
            )
        }
    };
    let _ = writeln!(s, "rig:        {rig_text}");
    let _ = writeln!(s, "thimble:    {} m", fmt_vec(&main.report.position_m));
    let _ = writeln!(
        s,
        "limits:     t_min = {} N, t_max = {} N; contact force |f_e| = {} N over {directions}",
        setup.limits.t_min_n, setup.limits.t_max_n, setup.force_n
    );
    let _ = writeln!(
        s,
        "algorithm:  {} with |f_c| = {} N, f_c = {} N",
        setup.algorithm.name(),
        setup.field_n,
        fmt_vec(&main.field_n)
    );
    let _ = writeln!(
        s,
        "isotropic force limit (radius of S_f): {:.4} N",
        main.report.isotropic_force_n
    );
    let _ = writeln!(
        s,
        "\ncomparison at this point (same |f_c|, |f_e|, limits):\n  alg  |f_c| dir   mean V  min V   mean|1-V|  exact   mean |f-f'e| N  isotropic N"
    );
    for alg in Algorithm::ALL {
        let setup_k = AnalysisSetup {
            algorithm: alg,
            ..*setup
        };
        let a = if alg == setup.algorithm {
            None
        } else {
            Some(analyse(request, &setup_k))
        };
        let a = a.as_ref().unwrap_or(main);
        let dir = match alg.field_rule() {
            videt_control::FieldRule::Constant => "-z      ",
            videt_control::FieldRule::Bisector => "bisector",
        };
        let sum = &a.summary;
        let _ = writeln!(
            s,
            "  {:<4} {dir}  {:>6.3}  {:>6.3}  {:>9.4}  {:>5.1}%  {:>14.4}  {:>10.4}",
            alg.name(),
            sum.mean_v,
            sum.min_v,
            sum.mean_miss,
            100.0 * sum.exact_share,
            sum.mean_error_n,
            a.report.isotropic_force_n
        );
    }
    s
}

/// Evaluate the V index of the setup for one planar direction (for plots).
fn planar_v(rig: &RigPlanar, at: &Vector2<f64>, setup: &AnalysisSetup, deg: f64) -> f64 {
    let map = rig.wire_map(at).expect("checked regular");
    let a = deg.to_radians();
    evaluate_direction(&map, &Vector2::new(a.cos(), a.sin()), setup).v
}

fn isotropic_grid<const N: usize, D: WireDevice<N>>(
    device: &D,
    point: impl Fn(f64, f64) -> nalgebra::SVector<f64, N>,
    setup: &AnalysisSetup,
    xs: &[f64],
    ys: &[f64],
    valid: impl Fn(&nalgebra::SVector<f64, N>) -> bool,
) -> Vec<Vec<Option<f64>>> {
    ys.iter()
        .map(|&y| {
            xs.iter()
                .map(|&x| {
                    let p = point(x, y);
                    if valid(&p) {
                        isotropic_limit_at(device, &p, setup)
                    } else {
                        None
                    }
                })
                .collect()
        })
        .collect()
}

mod plots {
    //! PNG plots with plotters (text in the font of [`crate::plotting`]).

    use super::*;
    use crate::plotting::{register_font, write_error as e, PlotError};
    use plotters::prelude::*;

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
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: AnalyzeArgs,
    }

    fn args(line: &[&str]) -> AnalyzeArgs {
        let mut v = vec!["analyze"];
        v.extend_from_slice(line);
        Cli::try_parse_from(v).expect("clap accepts").args
    }

    fn report(line: &[&str]) -> Report {
        let a = args(line);
        analyse(&parse_request(&a).unwrap(), &parse_setup(&a).unwrap()).report
    }

    #[test]
    fn paper_prototype_numbers() {
        let r = report(&[
            "--planar",
            "--guide",
            "0,0",
            "--guide",
            "0.52,0",
            "--at",
            "0.26,0.26",
            "--algorithm",
            "P1",
            "--fc",
            "2",
        ]);
        assert!((r.isotropic_force_n - std::f64::consts::SQRT_2).abs() < 1e-9);
        assert_eq!(r.v_index.len(), 360);
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json["algorithm"], "P1");
        assert_eq!(json["fc_n"], 2.0);
        assert_eq!(json["position_m"], serde_json::json!([0.26, 0.26]));
        assert_eq!(json["v_index"][90]["direction_deg"], 90.0);
        // Fig. 19: P1 without field renders nothing straight up, everything straight down.
        let r = report(&["--planar", "--algorithm", "P1"]);
        let v = |deg: usize| match r.v_index[deg] {
            VEntry::Planar { v, .. } => v,
            _ => unreachable!(),
        };
        assert!(v(90).abs() < 1e-12 && (v(270) - 1.0).abs() < 1e-12);
        assert_eq!(r.isotropic_force_n, 0.0);
    }

    #[test]
    fn spatial_rig_answers() {
        let r = report(&[
            "--guide",
            "0,0",
            "--guide",
            "0.4,0",
            "--guide",
            "0.1,0.35",
            "--at",
            "0.15,0.12,0.3",
            "--algorithm",
            "F2",
            "--fc",
            "2",
        ]);
        assert_eq!(r.v_index.len(), 2522);
        assert!(r.isotropic_force_n > 0.5);
    }

    #[test]
    fn bad_flags_are_explained() {
        let msg = |line: &[&str]| {
            let a = args(line);
            parse_request(&a)
                .and_then(|_| parse_setup(&a))
                .unwrap_err()
                .to_string()
        };
        assert!(msg(&["--guide", "0,0", "--guide", "1,0"]).contains("exactly 3 --guide"));
        assert!(msg(&["--planar", "--guide", "0,0"]).contains("exactly 2 --guide"));
        assert!(
            msg(&["--guide", "0,0", "--guide", "0.2,0", "--guide", "0.4,0"]).contains("degenerate")
        );
        assert!(msg(&["--planar", "--guide", "0,0", "--guide", "0.3,0.1"]).contains("Y must be 0"));
        assert!(msg(&["--planar", "--t-min", "3", "--t-max", "2"]).contains("t_min"));
        assert!(msg(&["--planar", "--at", "0.2,0"]).contains("in front of the guide plane"));
        assert!(msg(&["--planar", "--at", "0.2,3"]).contains("outside the workspace"));
        assert!(msg(&["--planar", "--at", "0.2"]).contains("expected 2"));
        assert!(msg(&["--at", "0.1,0.1,abc"]).contains("not a finite number"));
        assert!(msg(&["--planar", "--algorithm", "P9"]).contains("unknown"));
        assert!(msg(&["--planar", "--fc", "-1"]).contains("--fc"));
        assert!(msg(&["--planar", "--force", "0"]).contains("--force"));
    }

    #[test]
    fn plots_are_written() {
        let dir = tempfile::tempdir().unwrap();
        for line in [
            &["--planar", "--fc", "2"][..],
            &["--at", "0.2,0.1,0.3", "--algorithm", "QP", "--fc", "1"][..],
        ] {
            let a = args(line);
            let written = plots::write_all(
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
