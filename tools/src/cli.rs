//! The `videt` command line: the subcommands and what runs each. The binary parses it; the
//! manual pages and shell completions are generated from the same definitions (the `manual`
//! module), so they cannot drift from `videt --help`.

use clap::{Parser, Subcommand};

use crate::tool;
use crate::tool::ToolResult;

/// VIDET tool: calibration, wire replacement, analysis and demos.
#[derive(Debug, Parser)]
#[command(name = "videt", version, about, long_about = None)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands, one module of [`crate::tool`] each.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Configuration files: check one and print the resolved settings.
    #[command(subcommand)]
    Config(tool::config::ConfigCommand),
    /// Auto-initialize the rig: wind each wire in turn with the empty thimble connected, measure
    /// the base triangle, write the calibration.
    Init(tool::init::InitArgs),
    /// Commissioning check of a newly assembled rig (thimble detached): the computer's
    /// real-time set-up, each drive's wire, direction and encoder, each tension sensor, the
    /// e-stop, the vibrotactors; each step PASS/FAIL/SKIPPED with the fix.
    Commission(tool::commission::CommissionArgs),
    /// Wire maintenance: guided replacement.
    #[command(subcommand)]
    Wire(tool::wire::WireCommand),
    /// Two-point calibration of a wire's tension sensor with a known weight.
    TensionCalibrate(tool::tension_calibrate::TensionCalibrateArgs),
    /// Calibration age and validity, wires, whether the motors are in use.
    Status(tool::status::StatusArgs),
    /// Designer's analysis of a rig at a point: index V over force directions, isotropic force
    /// limit, plots (paper section 6).
    Analyze(tool::analyze::AnalyzeArgs),
    /// The paper's experiments on the twin (Figs. 18, 22, 23: the planar prototype following a
    /// profile with P1, exploring a surface in region C with a field; the one-wire device
    /// exploring a contour): runs them, writes the figures and a summary of each.
    Experiments(tool::experiments::ExperimentsArgs),
    /// The one-wire device's passive angle sensors: magnetic field, raw counts, angles and the
    /// thimble position by eq. 7 (or simulated encoders with --sim X,Y,Z).
    AngleSensors(tool::angle_sensors::AngleSensorsArgs),
    /// Colour-to-touch trainer's aid: the levels at a pixel, or the image in level colours.
    Colour(tool::colour::ColourArgs),
    /// Summarise a telemetry session log and export it as CSV.
    Log(tool::log::LogArgs),
    /// Replay a session log through the same control cycle code: bit-exact comparison of every
    /// output, or what other settings (--config, --algorithm) would have commanded.
    Replay(tool::replay::ReplayArgs),
    /// Talk to the running videtd: status, stop, release a wire, resume, reset faults.
    Service(tool::service::ServiceArgs),
    /// Measure the control loop's wake-up latency on this machine (compare with cyclictest).
    BenchRt(tool::bench_rt::BenchRtArgs),
    /// Haptic fidelity on the timing-faithful twin: rendered stiffness (P1, P2, regions A/B/C),
    /// Z-width against damping per tension sensor and rate, pop-through; tables, JSON, plots.
    BenchHaptic(tool::bench_haptic::BenchHapticArgs),
    /// Calibrate the stereo camera pair from chessboard image pairs and write the calibration.
    CalibrateStereo(tool::calibrate_stereo::CalibrateStereoArgs),
    /// Stereo pipeline on a rectified pair: segments, matches, 3D segments, overlays.
    Vision(tool::vision::VisionArgs),
    /// Serve the digital twin as a rig on a CAN interface: its CiA 402 drives, their motors the
    /// twin's, for a videtd in device mode (bench without the rig, kernel-in-the-loop tests).
    SimRig(tool::sim_rig::SimRigArgs),
    /// Soak videtd on the twin: random faults (sensor loss, wire break, e-stop, EMCY,
    /// heartbeat loss, bus-off, socket abuse, SIGHUP), each recovered as documented; checks the
    /// safe state within two periods, no panic, flat memory/fds/threads, complete session logs.
    Soak(tool::soak::SoakArgs),
}

impl Cli {
    /// Run the chosen subcommand.
    pub fn run(&self) -> ToolResult {
        match &self.command {
            Command::Config(c) => tool::config::run(c),
            Command::Init(a) => tool::init::run(a),
            Command::Commission(a) => tool::commission::run(a),
            Command::Wire(c) => tool::wire::run(c),
            Command::TensionCalibrate(a) => tool::tension_calibrate::run(a),
            Command::Status(a) => tool::status::run(a),
            Command::Analyze(a) => tool::analyze::run(a),
            Command::AngleSensors(a) => tool::angle_sensors::run(a),
            Command::Experiments(a) => tool::experiments::run(a),
            Command::Colour(a) => tool::colour::run(a),
            Command::Log(a) => tool::log::run(a),
            Command::Replay(a) => tool::replay::run(a),
            Command::Service(a) => tool::service::run(a),
            Command::BenchRt(a) => tool::bench_rt::run(a),
            Command::BenchHaptic(a) => tool::bench_haptic::run(a),
            Command::CalibrateStereo(a) => tool::calibrate_stereo::run(a),
            Command::Vision(a) => tool::vision::run(a),
            Command::SimRig(a) => tool::sim_rig::run(a),
            Command::Soak(a) => tool::soak::run(a),
        }
    }
}
