//! `videt service ...`: talk to the running `videtd` through its control socket.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Args;

use videt_service::socket::{request, Request, Response};

use super::ToolResult;

/// Talk to the running service.
#[derive(Debug, Args)]
pub struct ServiceArgs {
    /// The service's control socket.
    #[arg(long, default_value = "/run/videt/videtd.sock", global = true)]
    pub socket: PathBuf,
    /// Print the raw JSON reply.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to ask.
    #[command(subcommand)]
    pub command: Request,
}

/// Run `videt service`.
pub fn run(args: &ServiceArgs) -> ToolResult {
    let reply: Response =
        request(&args.socket, &args.command, Duration::from_secs(3)).map_err(|e| {
            let hint = if e.kind() == std::io::ErrorKind::PermissionDenied {
                "only root and members of the group videt may use it: usermod -aG videt NAME, then log in again"
            } else {
                "is the service running?"
            };
            format!("cannot reach videtd at {}: {e} ({hint})", args.socket.display())
        })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&reply)?);
    } else if let Some(s) = &reply.status {
        println!(
            "rate {:.1} Hz, {} periods, {} overruns, worst wake-up {:.1} µs",
            s.rate_hz, s.cycles, s.overruns, s.worst_wake_latency_us
        );
        println!(
            "safety: {}{}",
            s.safety,
            if s.power_off { " (drives off)" } else { "" }
        );
        println!(
            "thimble ({:+.4}, {:+.4}, {:+.4}) m; {} tensions {} N; {}",
            s.position_m[0],
            s.position_m[1],
            s.position_m[2],
            s.device,
            s.tensions_n
                .iter()
                .map(|t| format!("{t:.2}"))
                .collect::<Vec<_>>()
                .join(" "),
            if s.in_contact {
                format!("in contact, {:.2} N", s.force_n)
            } else {
                "free".to_string()
            }
        );
        if let Some(w) = s.released_wire {
            println!("wire {w} released for replacement");
        }
        if s.surface_stale {
            println!("surface stale: forces faded out");
        }
        if let Some(e) = &s.telemetry_error {
            println!(
                "session log NOT WRITING: {e} (periods lost so far: {})",
                s.telemetry_lost
            );
        } else if s.telemetry_lost + s.telemetry_dropped > 0 {
            println!(
                "session log: {} periods lost (disk), {} dropped (ring full)",
                s.telemetry_lost, s.telemetry_dropped
            );
        }
    } else if reply.ok {
        println!("ok");
    }
    match reply.error {
        Some(e) => Err(e.into()),
        None => Ok(ExitCode::SUCCESS),
    }
}
