//! `videtd` — the VIDET service: runs the real-time control loop of the haptic interface.
//!
//! `videtd --sim` runs the real runtime and control code on the digital twin (a virtual wall and
//! a virtual operator who touches it and slides along it). One status line per second; Ctrl-C or
//! SIGTERM ramps the forces out, powers the drives off and exits 0.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use clap::{Parser, ValueEnum};
use tracing::{error, info, warn};
use videt::can_twin::{self, CanTwin};
use videt::control_loop::{run_control_loop, start_hardware, LoopSettings};
use videt::cycle::WireZero;
use videt::status::status_channel;
use videt::twin_rt::RealTimeTwin;
use videt::{rt, setup};
use videt_rt_config::Config;

/// Which twin `--sim` runs on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SimMode {
    /// The HAL-level physics twin (fast).
    Hal,
    /// The twin's motors behind three simulated CiA 402 drives on a userspace CAN bus, driven
    /// by the real CANopen drive driver.
    Can,
}

/// VIDET service: the real-time control loop of the haptic interface.
#[derive(Debug, Parser)]
#[command(name = "videtd", version, about)]
struct Args {
    /// Run on the digital twin instead of the device.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "hal")]
    sim: Option<SimMode>,
    /// Configuration file (default: /etc/videt/videt.toml when present, else built-in defaults
    /// with --sim).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Stop cleanly after this many seconds.
    #[arg(long, value_name = "SECS")]
    duration: Option<f64>,
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
    let Some(mode) = args.sim else {
        error!("no device backend is built into this videtd: run with --sim for the digital twin");
        return ExitCode::from(2);
    };
    run_on_twin(&config, mode, args.duration)
}

fn run_on_twin(config: &Config, mode: SimMode, duration_s: Option<f64>) -> ExitCode {
    let rig = match setup::rig(config) {
        Ok(r) => r,
        Err(e) => {
            error!("rig geometry: {e}");
            return ExitCode::from(2);
        }
    };
    if config.realtime.lock_memory {
        if let Err(e) = rt::lock_memory() {
            warn!("memory not locked (mlockall: {e}); page faults may delay the control loop");
        }
    }
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        if let Err(e) = signal_hook::flag::register(signal, Arc::clone(&stop)) {
            error!("cannot install the handler for signal {signal}: {e}");
            return ExitCode::FAILURE;
        }
    }

    let scene = setup::demo_scene(config, 1);
    let wall = scene.wall;
    let mut cycle = setup::control_cycle(config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: config.control.rate_hz,
        duration_ns: duration_s.map(|d| (d * 1e9) as u64),
        max_consecutive_overruns: 10,
    };
    let (mut publisher, mut reader) = status_channel();
    let priority = config.realtime.control_priority;
    let cpu = usize::try_from(config.realtime.control_cpu).ok();
    let thread_stop = Arc::clone(&stop);
    let drive_config = can_twin::drive_config(config);
    info!(
        backend = match mode {
            SimMode::Hal => "hal twin",
            SimMode::Can => "CiA 402 drives on a userspace CAN bus",
        },
        "drive backend"
    );
    info!(
        rate_hz = settings.rate_hz,
        wall_z_m = scene.wall_z_m,
        "starting the control loop on the digital twin (virtual wall, virtual operator)"
    );
    let control = std::thread::Builder::new()
        .name("videt-control".into())
        .spawn(move || {
            let report = rt::setup_control_thread(priority, cpu);
            for w in &report.warnings {
                warn!("{w}");
            }
            match mode {
                SimMode::Hal => {
                    let mut hw = RealTimeTwin::new(scene.twin);
                    start_hardware(&mut hw).map_err(|e| e.to_string())?;
                    Ok::<_, String>(run_control_loop(
                        &mut hw,
                        &wall,
                        &mut cycle,
                        &settings,
                        &thread_stop,
                        &mut publisher,
                    ))
                }
                SimMode::Can => {
                    let mut hw = CanTwin::new(scene.twin, drive_config)?;
                    start_hardware(&mut hw).map_err(|e| e.to_string())?;
                    Ok(run_control_loop(
                        &mut hw,
                        &wall,
                        &mut cycle,
                        &settings,
                        &thread_stop,
                        &mut publisher,
                    ))
                }
            }
        });
    let control = match control {
        Ok(handle) => handle,
        Err(e) => {
            error!("cannot start the control thread: {e}");
            return ExitCode::FAILURE;
        }
    };

    let mut last_print = std::time::Instant::now();
    while !control.is_finished() {
        std::thread::sleep(Duration::from_millis(20));
        if last_print.elapsed() >= Duration::from_secs(1) {
            last_print = std::time::Instant::now();
            println!("{}", reader.latest().line());
        }
    }
    match control.join() {
        Ok(Ok(report)) => {
            let s = reader.latest();
            println!("{}", s.line());
            info!(
                cycles = report.cycles,
                overruns = report.overruns,
                safety = report.final_safety.as_str(),
                "control loop stopped: forces ramped out, drives off"
            );
            if stop.load(Ordering::Relaxed) {
                info!("stopped by signal");
            }
            ExitCode::SUCCESS
        }
        Ok(Err(e)) => {
            error!("{e}");
            ExitCode::FAILURE
        }
        Err(_) => {
            error!("the control thread panicked; the drives were left to their communication-loss stop");
            ExitCode::from(70)
        }
    }
}
