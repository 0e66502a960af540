//! Subcommands of the `videt` tool, one module each. Each exposes its clap arguments and a `run`
//! function returning the process exit code or an error to print.

pub mod analyze;
pub mod angle_sensors;
pub mod bench_haptic;
pub mod bench_rt;
pub mod calibrate_stereo;
pub mod colour;
pub mod commission;
pub mod config;
pub mod device;
pub mod experiments;
pub mod init;
pub mod log;
pub mod log_plots;
pub mod motors;
pub mod replay;
pub mod service;
pub mod sim_rig;
pub mod soak;
pub mod status;
pub mod tension_calibrate;
pub mod through_service;
pub mod view_figure;
pub mod vision;
pub mod wire;

/// The error a subcommand reports to the user (printed as `videt: <message>`).
pub type ToolError = Box<dyn std::error::Error + Send + Sync>;

/// What a subcommand returns: the exit code, or an error to print (exit code 1).
pub type ToolResult = Result<std::process::ExitCode, ToolError>;
