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
//!
//! This file holds the command line (`AnalyzeArgs` and its validation) and the run; `request`
//! holds the validated request and the analysed workspace, `analysis` the sweeps and the numbers
//! they give, `text` the text report and `plots` the PNG figures.

mod analysis;
mod plots;
mod request;
mod text;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use nalgebra::Vector2;
use videt_control::analysis::AnalysisSetup;
use videt_control::{Algorithm, ForceLimits, Rig3, RigPlanar, Vec3};

use super::ToolResult;
use analysis::analyse;
pub use request::{
    check_planar_point, check_spatial_point, Request, MAX_WIRE_LENGTH_M, MIN_HEIGHT_M,
};
use text::text_report;

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

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Debug, Parser)]
    struct Cli {
        #[command(flatten)]
        args: AnalyzeArgs,
    }

    pub(super) fn args(line: &[&str]) -> AnalyzeArgs {
        let mut v = vec!["analyze"];
        v.extend_from_slice(line);
        Cli::try_parse_from(v).expect("clap accepts").args
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
}
