//! `videtd` — the VIDET service: runs the real-time control loop of the haptic interface.
//!
//! `videtd --sim` runs the real runtime and control code on the digital twin (a virtual wall and
//! a virtual operator who touches it and slides along it). One status line per second; Ctrl-C or
//! SIGTERM ramps the forces out, powers the drives off and exits 0. Under systemd
//! (`Type=notify`) it reports READY=1 once the drives are enabled and pets the watchdog while the
//! control loop is healthy.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, ValueEnum};
use tracing::error;
use videt::cycle::WireZero;
use videt::service::{run_service, ServiceOptions};
use videt::setup;
use videt::snapshot::FixedSurface;
use videt::twin_rt::RealTimeTwin;
use videt_rt_config::Config;

/// Which twin `--sim` runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimMode {
    /// The HAL-level physics twin (fast).
    Hal,
}

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version, about)]
struct Args {
    /// Run on the digital twin instead of the device.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "hal")]
    sim: Option<SimMode>,
    /// Configuration file (default: /etc/videt/videt.toml when present; with --sim, built-in
    /// defaults otherwise).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    #[arg(long, value_name = "SECS")]
    duration: Option<f64>,
    /// Control socket path (overrides socket.path).
    #[arg(long, value_name = "PATH")]
    socket: Option<PathBuf>,
    /// Run without the control socket.
    #[arg(long, conflicts_with = "socket")]
    no_socket: bool,
    /// Directory of the session log (overrides telemetry.directory).
    #[arg(long, value_name = "DIR")]
    telemetry_dir: Option<PathBuf>,
    /// Run without the per-period telemetry log.
    #[arg(long, conflicts_with = "telemetry_dir")]
    no_telemetry: bool,
}

const DEFAULT_CONFIG: &str = "/etc/videt/videt.toml";

fn load_config(args: &Args) -> Result<Config, String> {
    match &args.config {
        Some(path) => Config::load(path).map_err(|e| e.to_string()),
        None if std::path::Path::new(DEFAULT_CONFIG).exists() => {
            Config::load(std::path::Path::new(DEFAULT_CONFIG)).map_err(|e| e.to_string())
        }
        None if args.sim.is_some() => Ok(Config::default()),
        None => Err(format!(
            "no configuration: pass --config FILE or install {DEFAULT_CONFIG}"
        )),
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let args = Args::parse();
    let config = match load_config(&args) {
        Ok(c) => c,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    };
    if let Some(d) = args.duration {
        if !(d.is_finite() && d > 0.0) {
            error!("--duration must be a positive number of seconds, got {d}");
            return ExitCode::from(2);
        }
    }
    let mut options = ServiceOptions::from_config(config.clone());
    options.duration_s = args.duration;
    if args.no_socket {
        options.socket_path = None;
    } else if let Some(p) = &args.socket {
        options.socket_path = Some(p.clone());
    }
    if args.no_telemetry {
        options.telemetry_dir = None;
    } else if let Some(d) = &args.telemetry_dir {
        options.telemetry_dir = Some(d.clone());
    }
    let rig = match setup::rig(&config) {
        Ok(r) => r,
        Err(e) => {
            error!("rig geometry: {e}");
            return ExitCode::from(2);
        }
    };
    match args.sim {
        Some(SimMode::Hal) => {
            let scene = setup::demo_scene(&config, 1);
            tracing::info!(
                rate_hz = config.control.rate_hz,
                wall_z_m = scene.wall_z_m,
                "digital twin: a virtual wall, a virtual operator touching it and sliding along it"
            );
            let cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
            // Colour under the finger: a demo image over the explored area.
            match videt::colour_thread::demo_colour(&config.rig.guides_m, scene.wall_z_m) {
                Ok(source) => options.colour = Some(source),
                Err(e) => tracing::warn!("colour rendering disabled: {e}"),
            }
            run_service(
                RealTimeTwin::new(scene.twin),
                FixedSurface(scene.wall),
                cycle,
                &options,
            )
        }
        None => {
            error!(
                "no device backend is built into this videtd: run with --sim for the digital twin"
            );
            ExitCode::from(2)
        }
    }
}
