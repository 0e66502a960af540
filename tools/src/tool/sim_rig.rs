//! `videt sim-rig`: the digital twin served as a rig on a CAN interface. Its three CiA 402
//! drives answer on `--can` with the node ids, rated torque and heartbeat of the configuration,
//! their motors the twin's (wires, thimble, a virtual operator touching the check wall and
//! sliding along it), each drive's analog input the strain-gauge reading of its wire. A
//! `videtd` in device mode on the same interface then drives the twin through the kernel's CAN
//! stack exactly as it drives the rig: a bench for the backpack computer without the rig, and
//! the stand-in the kernel-in-the-loop suite runs the service against.
//!
//! Signals inject the faults a real drive reports: SIGUSR1 latches an over-current fault in
//! wire 0's drive (it sends an EMCY and goes to its fault state), SIGUSR2 removes the cause
//! (a fault reset from the host then clears it).

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;
use videt_runtime::WIREMAN_WIRES;

use clap::Args;
use videt_assembly::as_built::WiringMistake;
use videt_config::Config;
use videt_control::autoinit::BaseTriangle;
use videt_sim::cia402_node::{MotorPlant, SharedMotors, SimDriveBank, SimDriveSpec};
use videt_sim::twin_plant::{AnalogScale, RealTimeTwinPlant};

use super::ToolResult;
use videt_runtime::{rt, setup};

/// How often the physics thread brings the twin up to the wall clock and publishes its
/// encoders and strain gauges to the drives (the twin integrates at its own 20 kHz step
/// within). Half a control period at 1 kHz: what a drive reports at SYNC is at most this old,
/// as a real drive's encoder latch is, and an emulated CPU is not woken 5000 times a second.
const PHYSICS_PERIOD: Duration = Duration::from_micros(500);

/// The EMCY error code of the injected drive fault: over-current (CiA 301 0x2310).
const OVER_CURRENT: u16 = 0x2310;

/// Serve the digital twin's drives on a CAN interface.
#[derive(Debug, Args)]
pub struct SimRigArgs {
    /// The service's configuration: the rig's guides and transmission, the drives' node ids,
    /// rated torque and heartbeat, the strain gauges' scale.
    #[arg(long)]
    pub config: PathBuf,
    /// CAN interface to serve (default: the configuration's `drives.can_interface`).
    #[arg(long)]
    pub can: Option<String>,
    /// Write the twin's true calibration (its guides, encoder zeros at free length zero) to
    /// this file, as `videt init` would measure it, once the drives listen.
    #[arg(long)]
    pub calibration_out: Option<PathBuf>,
    /// SCHED_FIFO priority of the drives' thread, the physics thread one below (0: normal
    /// scheduling).
    #[arg(long, default_value_t = 0)]
    pub priority: u8,
    /// Pin the drives' thread to this CPU. Give it the control thread's
    /// (`realtime.control_cpu`): each period's SYNC and answers are then handed over on one
    /// CPU, whatever load stalls the others, as hardware answers whatever the host does.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// Stop after this many seconds (default: until SIGTERM or Ctrl-C).
    #[arg(long)]
    pub seconds: Option<f64>,
    /// The drives' EDS or DCF: the simulated drives hold the objects, access, PDO mappability
    /// and defaults it gives and answer as CiA 301 says for each refused request (default: the
    /// configuration's `drives.device_description`, else the generic CiA 402 profile).
    #[arg(long)]
    pub drive_description: Option<PathBuf>,
    /// Start the rig at rest for commissioning or initialization: every wire detached from
    /// the thimble and fully wound, its sphere against its ring (default: the thimble
    /// connected, a virtual operator touching the check wall).
    #[arg(long)]
    pub at_rest: bool,
    /// Build the rig with a wiring mistake (repeatable): reversed-motor:N, reversed-encoder:N,
    /// swapped-nodes:A,B, inverted-cell:N. The drives' configuration does not correct it: the
    /// service's does, as on a real rig. With swapped nodes the drives carry the configured
    /// ids in ascending order, then swapped.
    #[arg(long, value_name = "MISTAKE")]
    pub sim_fault: Vec<String>,
    /// Take a technician's hands from stdin, a line each: `pull-out RING METRES` pulls that
    /// wire's sphere out of its ring by that much (and holds it there), `let-go RING` lets it
    /// go.
    #[arg(long)]
    pub technician_stdin: bool,
    /// The twin's world in slow motion: seconds of its time per second of the wall clock, in
    /// (0, 1]. For a machine that runs the control loop well below its rate (an emulated CPU):
    /// at a quarter of the rate, 0.25 keeps a period per millisecond of the twin's world, as on
    /// the backpack (the bus, its heartbeats and timeouts keep the wall clock).
    #[arg(long, default_value_t = 1.0)]
    pub time_scale: f64,
}

/// The twin's true calibration record for `config`'s rig.
pub fn true_calibration(config: &Config) -> Result<videt_config::calibration::Calibration, String> {
    let rig = setup::rig(config).map_err(|e| format!("rig.guides_m: {e}"))?;
    let g = rig.guides_m();
    let d = |a: usize, b: usize| (g[a] - g[b]).norm();
    let measurement = videt_service::init::session::Measurement {
        triangle: BaseTriangle {
            sides_m: [d(0, 1), d(0, 2), d(1, 2)],
            residuals_m: [0.0; 6],
            rig,
        },
        zero_counts: [0; WIREMAN_WIRES],
        metres_per_count: setup::transmission(config).metres_per_count(),
    };
    Ok(videt_service::init::session::outcome(
        config,
        "sim-rig (the twin's true geometry)",
        &measurement,
    )
    .calibration)
}

/// Run `videt sim-rig`.
pub fn run(args: &SimRigArgs) -> ToolResult {
    let config = Config::load(&args.config)?;
    if !(args.time_scale > 0.0 && args.time_scale <= 1.0) {
        return Err(format!(
            "--time-scale {}: seconds of the twin's time per wall-clock second, in (0, 1]",
            args.time_scale
        )
        .into());
    }
    if let Some(cpu) = args.cpu {
        if !rt::cpu_allowed(cpu) {
            return Err(format!(
                "--cpu {cpu}: this process may run on CPUs {}",
                rt::cpu_list(&rt::allowed_cpus())
            )
            .into());
        }
    }
    let interface = args
        .can
        .clone()
        .unwrap_or_else(|| config.drives.can_interface.clone());
    let mistakes = args
        .sim_fault
        .iter()
        .map(|text| wiring_mistake(text))
        .collect::<Result<Vec<_>, _>>()?;
    let port = videt_sim::can_bus::socketcan::SocketCanEndpoint::open(&interface)
        .map_err(|e| format!("CAN interface {interface}: {e} (--can, drives.can_interface)"))?;
    let twin = if args.at_rest {
        // The HAL twin is wired straight: the service's drivers apply its corrections.
        let mut twin = videt_service::init::twin::rest_twin(
            &config,
            &videt_service::init::twin::TwinSetup::from_config(&config, 1),
        );
        twin.set_wiring(videt_sim::Wiring::default());
        twin
    } else {
        videt_assembly::twin_scene::wireman_wall_scene(&config, 1).twin
    };
    let s = &config.sensors;
    let scales: [AnalogScale; WIREMAN_WIRES] = core::array::from_fn(|i| AnalogScale {
        zero_counts: s.zero_counts[i],
        newtons_per_count: if mistakes.contains(&WiringMistake::InvertedCell(i)) {
            -s.newtons_per_count[i]
        } else {
            s.newtons_per_count[i]
        },
    });
    // The physics runs on a thread of its own and hands encoders, analog inputs and torques to
    // the drives through wait-free mailboxes: the drives answer every SYNC at once whatever the
    // physics costs (on a slow machine the twin then moves in slow motion rather than the bus
    // falling silent). With `--priority` it runs just below the drives: a physics thread
    // starved by the machine's ordinary work would catch up in bursts, and a burst of motion
    // between two SYNCs reads as a spike of wire speed.
    let mut plant = RealTimeTwinPlant::new(twin, scales).with_time_scale(args.time_scale);
    let motors = Arc::new(SharedMotors::new(WIREMAN_WIRES));
    publish(&plant, &motors);
    // The drives carry the configured ids on wires 0, 1, 2; a rig built with drives swapped
    // carries them in ascending order, then swapped (as `videt commission --sim` builds it:
    // reordering the configuration's ids then fixes it).
    let built_ids = if mistakes
        .iter()
        .any(|m| matches!(m, WiringMistake::SwappedNodes(..)))
    {
        videt_assembly::as_built::built_node_ids(config.drives.node_ids, &mistakes)
    } else {
        config.drives.node_ids
    };
    let specs: Vec<SimDriveSpec> = (0..WIREMAN_WIRES)
        .map(|axis| SimDriveSpec {
            node_id: built_ids[axis],
            axis,
            rated_torque_mnm: setup::twin_rated_torque_mnm(&config),
            boot_delay: Duration::from_millis(20),
        })
        .collect();
    let priority = args.priority;
    let cpu = args.cpu;
    let stop = Arc::new(AtomicBool::new(false));
    for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(signal, Arc::clone(&stop))?;
    }
    let raise = Arc::new(AtomicBool::new(false));
    let clear = Arc::new(AtomicBool::new(false));
    signal_hook::flag::register(signal_hook::consts::SIGUSR1, Arc::clone(&raise))?;
    signal_hook::flag::register(signal_hook::consts::SIGUSR2, Arc::clone(&clear))?;
    let dictionary = match &args.drive_description {
        Some(path) => Some(Arc::new(videt_assembly::drive_dictionary::for_file(
            path, &config,
        )?)),
        None => videt_assembly::drive_dictionary::for_config(&config)?,
    };
    let part = dictionary.as_ref().map_or_else(
        || "the generic CiA 402 profile".to_string(),
        |d| d.source.clone(),
    );
    let bank =
        SimDriveBank::spawn_described(port, &specs, dictionary, Arc::clone(&motors), move || {
            if priority > 0 {
                if let Err(e) = rt::set_fifo(priority) {
                    eprintln!("videt sim-rig: the drives stay SCHED_OTHER: {e}");
                }
            }
            if let Some(cpu) = cpu {
                if let Err(e) = rt::pin_to_cpu(cpu) {
                    eprintln!("videt sim-rig: the drives are not pinned to CPU {cpu}: {e}");
                }
            }
        });
    for m in &mistakes {
        match *m {
            WiringMistake::ReversedMotor(w) => bank.faults(w).set_reversed_motor(true),
            WiringMistake::ReversedEncoder(w) => bank.faults(w).set_reversed_encoder(true),
            _ => {}
        }
    }
    let hands = args.technician_stdin.then(technician_hands);
    let physics_stop = Arc::clone(&stop);
    let physics_motors = Arc::clone(&motors);
    let physics = std::thread::Builder::new()
        .name("sim-rig-physics".into())
        .spawn(move || {
            if priority > 1 {
                if let Err(e) = rt::set_fifo(priority - 1) {
                    eprintln!("videt sim-rig: the physics stays SCHED_OTHER: {e}");
                }
            }
            while !physics_stop.load(Ordering::Relaxed) {
                while let Some(Ok((ring, pull_m))) = hands.as_ref().map(|h| h.try_recv()) {
                    if let Some(m) = pull_m {
                        let before = plant.twin().plant().free_length_m()[ring];
                        plant.twin_mut().plant_mut().set_free_length_m(ring, m);
                        eprintln!(
                            "videt sim-rig: wire {ring} pulled out from {:.1} mm to {:.1} mm",
                            before * 1e3,
                            m * 1e3
                        );
                    }
                }
                let torques = core::array::from_fn(|axis| physics_motors.torque_nm(axis));
                plant.apply_torques(&torques);
                publish(&plant, &physics_motors);
                std::thread::sleep(PHYSICS_PERIOD);
            }
        })?;
    // Written once the drives listen: a service started when the file appears finds them.
    if let Some(path) = &args.calibration_out {
        true_calibration(&config)?.save(path)?;
        eprintln!(
            "videt sim-rig: wrote the twin's calibration to {}",
            path.display()
        );
    }
    eprintln!(
        "videt sim-rig: drives {:?} on {interface} ({part}), the twin's wires and operator behind them{}",
        config.drives.node_ids,
        if args.time_scale < 1.0 {
            format!(" (its world at {} of the wall clock's speed)", args.time_scale)
        } else {
            String::new()
        },
    );
    let started = std::time::Instant::now();
    let mut powers = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        // Every change of the drives' power states, with the torque they apply: the record of
        // what the motors did while the service started, stopped or died.
        let views = bank.views();
        let now: Vec<_> = views.iter().map(|v| v.power).collect();
        if now != powers {
            let states: Vec<String> = views
                .iter()
                .zip(&config.drives.node_ids)
                .map(|(v, id)| format!("{id}: {:?} {:.3} N·m", v.power, v.applied_torque_nm))
                .collect();
            // This loop looks every 5 ms and its line reaches the journal later still: the time
            // the last of the drives changed, as their own thread saw it, is the record.
            let changed_at = views.iter().filter_map(|v| v.power_since).max();
            let at = changed_at.map_or_else(String::new, |t| {
                format!(" (changed at {:.6} s)", monotonic_s(t))
            });
            eprintln!("videt sim-rig: drive power {}{at}", states.join(", "));
            powers = now;
        }
        if args
            .seconds
            .is_some_and(|s| started.elapsed().as_secs_f64() >= s)
        {
            break;
        }
        if raise.swap(false, Ordering::Relaxed) {
            eprintln!(
                "videt sim-rig: wire 0's drive faults (over-current, EMCY 0x{OVER_CURRENT:04X})"
            );
            bank.faults(0).raise_fault(OVER_CURRENT);
        }
        if clear.swap(false, Ordering::Relaxed) {
            eprintln!("videt sim-rig: wire 0's drive fault cause removed");
            bank.faults(0).clear_fault();
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    stop.store(true, Ordering::Relaxed);
    let _ = physics.join();
    Ok(ExitCode::SUCCESS)
}

/// A wiring mistake `videt sim-rig` builds in (the e-stop's and the cameras' are not its).
fn wiring_mistake(text: &str) -> Result<WiringMistake, String> {
    match WiringMistake::parse(text) {
        Some(Ok(WiringMistake::EStopLevel | WiringMistake::SwappedCameras)) => Err(format!(
            "--sim-fault {text}: not a mistake of the drives or their cells (wire the e-stop line or the cameras that way instead)"
        )),
        Some(m) => m,
        None => Err(format!(
            "--sim-fault {text:?}: must be reversed-motor:N, reversed-encoder:N, swapped-nodes:A,B or inverted-cell:N"
        )),
    }
}

/// The technician's hands, read from stdin on a thread of their own: `(ring, Some(metres))`
/// to pull a wire out and hold it, `(ring, None)` to let it go. A line that is neither is
/// said on stderr and ignored.
fn technician_hands() -> std::sync::mpsc::Receiver<(usize, Option<f64>)> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lines() {
            let Ok(line) = line else { break };
            let words: Vec<&str> = line.split_whitespace().collect();
            let ring = |w: &str| w.parse::<usize>().ok().filter(|r| *r < WIREMAN_WIRES);
            let hand = match words.as_slice() {
                ["pull-out", r, m] => ring(r).zip(
                    m.parse::<f64>()
                        .ok()
                        .filter(|m| m.is_finite() && (0.0..=1.0).contains(m))
                        .map(Some),
                ),
                ["let-go", r] => ring(r).map(|r| (r, None)),
                _ => None,
            };
            match hand {
                Some(h) => {
                    eprintln!("videt sim-rig: the technician: {line}");
                    if tx.send(h).is_err() {
                        break;
                    }
                }
                None => eprintln!(
                    "videt sim-rig: {line:?}: the technician does `pull-out RING METRES` or `let-go RING`"
                ),
            }
        }
    });
    rx
}

/// `at` on the system's monotonic clock (`CLOCK_MONOTONIC`, the journal's and systemd's
/// monotonic timestamps), seconds.
fn monotonic_s(at: std::time::Instant) -> f64 {
    use videt_hal::Clock;
    let now = videt_runtime::rt::SystemClock.now();
    now.0 as f64 * 1e-9
        - std::time::Instant::now()
            .saturating_duration_since(at)
            .as_secs_f64()
}

/// The twin's encoders and strain-gauge readings, as the drives report them.
fn publish(plant: &RealTimeTwinPlant<WIREMAN_WIRES, videt_control::Rig3>, motors: &SharedMotors) {
    for axis in 0..WIREMAN_WIRES {
        let (counts, counts_per_s) = plant.encoder(axis);
        motors.publish_encoder(axis, counts, counts_per_s);
        motors.publish_analog_input(axis, plant.analog_input(axis));
    }
}
