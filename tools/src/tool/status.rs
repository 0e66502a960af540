//! `videt status`: the calibration (age, sides, workspace), the wires, whether the motors are in
//! use, and the running service's safety state, drives and tensions.

use std::process::ExitCode;
use std::time::{SystemTime, UNIX_EPOCH};

use clap::Args;
use videt_config::calibration::{backup_path, Calibration};

use super::device::{Exit, DEFAULT_CONFIG, EXIT_USAGE};
use super::ToolResult;
use std::time::Duration;
use videt_service::init::MotorsLock;
use videt_service::socket::{request, Request};

/// Arguments of `videt status`.
#[derive(Debug, Args)]
pub struct StatusArgs {
    /// Configuration file (default: /etc/videt/videt.toml when present, else built-in defaults).
    #[arg(long, value_name = "FILE")]
    pub config: Option<std::path::PathBuf>,
    /// Calibration file (default: `files.calibration` of the configuration).
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<std::path::PathBuf>,
    /// Motors lock file (default: `files.motors_lock`).
    #[arg(long, value_name = "FILE")]
    pub lock: Option<std::path::PathBuf>,
    /// The service's control socket (default: `socket.path`): when videtd answers, its safety
    /// state, drives and tensions are shown too.
    #[arg(long, value_name = "PATH")]
    pub socket: Option<std::path::PathBuf>,
    /// Print JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// How old, in words.
fn age_words(s: u64) -> String {
    match s {
        0..=119 => format!("{s} s"),
        120..=7199 => format!("{} min", s / 60),
        7200..=172_799 => format!("{} h", s / 3600),
        _ => format!("{} days", s / 86_400),
    }
}

/// Run `videt status`. Exit code 0 when the rig is calibrated, 4 when it is not (no valid
/// calibration: `videtd` will not render forces).
pub fn run(args: &StatusArgs) -> ToolResult {
    Ok(status(args).unwrap_or_else(|e| e.report(args.json)))
}

fn status(args: &StatusArgs) -> Result<ExitCode, Exit> {
    let config = match &args.config {
        Some(p) => videt_config::Config::load(p),
        None if std::path::Path::new(DEFAULT_CONFIG).exists() => {
            videt_config::Config::load(std::path::Path::new(DEFAULT_CONFIG))
        }
        None => Ok(videt_config::Config::default()),
    }
    .map_err(|e| Exit::new(EXIT_USAGE, "config", e.to_string()))?;
    let path = args
        .calibration
        .clone()
        .unwrap_or_else(|| config.files.calibration.clone().into());
    let lock_path = args
        .lock
        .clone()
        .unwrap_or_else(|| config.files.motors_lock.clone().into());
    // Whether a process drives the motors (taking the lock and letting it go at once).
    let motors = match MotorsLock::acquire(&lock_path) {
        Ok(_) => "free".to_string(),
        Err(e) => e.to_string(),
    };
    // The running service, if any: safety state, drives, tensions.
    let socket = args
        .socket
        .clone()
        .unwrap_or_else(|| config.socket.path.clone().into());
    let service = if socket.exists() {
        request(&socket, &Request::Status, Duration::from_secs(2))
            .ok()
            .and_then(|r| r.status)
    } else {
        None
    };
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let calibration = Calibration::load(&path);
    let backup = backup_path(&path);
    let has_backup = backup.exists();
    if args.json {
        let cal = match &calibration {
            Ok(c) => serde_json::json!({
                "valid": true,
                "created_utc": c.created_utc,
                "age_s": c.age_s(now),
                "source": c.source,
                "sides_m": c.sides_m,
                "residuals_m": c.residuals_m,
                "guides_m": c.guides_m,
                "wire_zero_counts": c.wire_zero_counts,
                "workspace_volume_m3": c.workspace.volume_m3,
                "required_wire_length_m": c.workspace.required_length_m,
            }),
            Err(e) => serde_json::json!({"valid": false, "reason": e.to_string()}),
        };
        println!(
            "{}",
            serde_json::json!({
                "calibration_file": path.display().to_string(),
                "backup": has_backup,
                "calibration": cal,
                "motors": motors,
                "service": service,
            })
        );
    } else {
        println!("calibration file: {}", path.display());
        match &calibration {
            Ok(c) => {
                println!(
                    "  valid, measured {} ({} ago) on the {}",
                    c.created_utc,
                    age_words(c.age_s(now)),
                    c.source
                );
                println!(
                    "  sides d01 {:.2} mm, d02 {:.2} mm, d12 {:.2} mm; largest residual {:.3} mm",
                    c.sides_m[0] * 1e3,
                    c.sides_m[1] * 1e3,
                    c.sides_m[2] * 1e3,
                    c.residuals_m.iter().fold(0.0_f64, |a, r| a.max(r.abs())) * 1e3
                );
                for i in 0..3 {
                    println!(
                        "  wire {i}: guide ({:.1}, {:.1}) mm, encoder zero {} counts, must be usable to {:.0} mm",
                        c.guides_m[i][0] * 1e3,
                        c.guides_m[i][1] * 1e3,
                        c.wire_zero_counts[i],
                        c.workspace.required_length_m[i] * 1e3
                    );
                }
                println!("  workspace {:.2} litres", c.workspace.volume_m3 * 1e3);
            }
            Err(e) => println!("  NOT CALIBRATED: {e}\n  videtd will not render forces until `videt init` succeeds"),
        }
        println!(
            "backup: {}",
            if has_backup {
                backup.display().to_string()
            } else {
                "none".into()
            }
        );
        println!("motors: {motors}");
        match &service {
            Some(s) => println!(
                "videtd: running{}, safety {}{}, drives {}, tensions ({}) N, released wire {}, {:.0} Hz, {} overruns",
                s.procedure
                    .as_deref()
                    .map_or(String::new(), |p| format!(" (procedure `{p}` under way)")),
                s.safety,
                s.fault
                    .as_deref()
                    .map_or(String::new(), |f| format!(" ({f})")),
                if s.power_off { "off" } else { "on" },
                s.tensions_n
                    .iter()
                    .map(|t| format!("{t:.2}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                s.released_wire.map_or("none".to_string(), |w| w.to_string()),
                s.rate_hz,
                s.overruns
            ),
            None => println!("videtd: not answering on {}", socket.display()),
        }
        for d in service.iter().flat_map(|s| &s.drives) {
            println!(
                "  drive of wire {} (node {}): {}",
                d.wire,
                d.node,
                d.identity()
            );
        }
    }
    Ok(if calibration.is_ok() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(4)
    })
}
