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
/// What the twin's operator touches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimScene {
    /// A flat virtual wall.
    Wall,
    /// A bas-relief box built by the surface builder from known segments, rebuilt every second
    /// on a vision thread and rendered through the proxy.
    Box,
}

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
    /// With --sim: the scene the virtual operator touches.
    #[arg(long, value_enum, default_value = "wall")]
    scene: SimScene,
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
        Some(SimMode::Hal) if args.scene == SimScene::Box => {
            run_relief_demo(&config, rig, &options)
        }
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

/// The twin with the bas-relief box: built at start-up, rebuilt every second on a vision thread,
/// rendered through the proxy with blended swaps.
fn run_relief_demo(
    config: &Config,
    rig: videt_control::Rig3,
    options: &ServiceOptions,
) -> ExitCode {
    use videt::relief_feed::relief_channel;
    use videt::relief_scene::{blend_params, box_operator, box_relief, proxy_params, ReliefLayout};

    let layout = ReliefLayout::for_config(config);
    let (model, report) = match box_relief(&layout, 0.0) {
        Ok(m) => m,
        Err(e) => {
            error!("surface: {e}");
            return ExitCode::FAILURE;
        }
    };
    tracing::info!(
        vertices = report.vertices,
        triangles = report.triangles,
        constraints = report.constraints_kept,
        build_us = (report.timings.cleaning
            + report.timings.crossings
            + report.timings.triangulation
            + report.timings.model)
            .as_micros() as u64,
        "digital twin: a bas-relief box, a virtual operator sliding over it and off its edge"
    );
    let period_s = 1.0 / f64::from(config.control.rate_hz);
    let (mut writer, feed) = match relief_channel(
        model,
        proxy_params(),
        blend_params(config),
        config.control.stiffness_n_per_m,
        period_s,
    ) {
        Ok(c) => c,
        Err(e) => {
            error!("{e}");
            return ExitCode::from(2);
        }
    };
    let vision = std::thread::Builder::new()
        .name("videt-vision".into())
        .spawn(move || loop {
            std::thread::sleep(std::time::Duration::from_secs(1));
            match box_relief(&layout, 0.0) {
                Ok((model, _)) => {
                    writer.publish(model);
                }
                Err(e) => tracing::warn!("surface rebuild failed: {e}"),
            }
        });
    if let Err(e) = vision {
        error!("cannot start the vision thread: {e}");
        return ExitCode::FAILURE;
    }
    let mut scene = setup::demo_scene(config, 1);
    let start = scene.twin.plant().position_m();
    scene.twin.set_operator(box_operator(&layout, start, 6.0));
    let cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    run_service(RealTimeTwin::new(scene.twin), feed, cycle, options)
}
