//! `videt replay LOG`: re-run a recorded session through the same control cycle code and
//! compare every output with the recorded one; with `--config`/`--algorithm`, what other
//! settings would have commanded along the same session.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use serde::Serialize;

use crate::replay::{
    replay, session_text, unrecorded_config_keys, Replay, ReplayOverrides, UnrecordedKey,
};
use videt_runtime::cycle::CycleRecord;
use videt_runtime::telemetry::{parse_log, Log};

use super::ToolResult;

/// Exit code when the replayed outputs differ from the recorded ones (no override given).
pub const EXIT_DIVERGED: u8 = 3;

/// Replay a session log through the control cycle and compare the outputs.
#[derive(Debug, Args)]
pub struct ReplayArgs {
    /// The session log (`videt-<time>.vlog`, written by videtd).
    pub logfile: PathBuf,
    /// Re-run with this configuration instead of the recorded one.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Re-run with this force-distribution algorithm (P1, P2, F1, F2, QP).
    #[arg(long, value_name = "NAME")]
    pub algorithm: Option<String>,
    /// Write the recorded and the replayed outputs side by side as CSV (default with
    /// `--config`/`--algorithm`: `<LOG>.replay.csv` beside the log).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Draw the replayed session's figures into this directory (path.png, tensions.png,
    /// forces.png, timing.png) and replay.png, recorded against replayed.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
}

/// The report of a replay.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayReport {
    /// Records in the log.
    pub records: usize,
    /// Periods replayed and compared.
    pub replayed: usize,
    /// Procedure periods skipped (not the control cycle's).
    pub procedure_periods: usize,
    /// Periods whose outputs differ.
    pub divergent_periods: usize,
    /// The first divergence, in words.
    pub first_divergence: Option<String>,
    /// Why the replay stopped before the end, if it did.
    pub stopped_early: Option<String>,
    /// What could not be read of the log, if anything.
    pub damage: Option<String>,
    /// The session closed its log (an end frame).
    pub closed: bool,
    /// How the session ended: as the end frame says, or that it ended without closing.
    pub end: String,
    /// Largest |replayed - recorded| tension set-point per wire, N.
    pub max_setpoint_difference_n: [f64; 3],
    /// Largest |replayed - recorded| torque command per wire, N·m.
    pub max_torque_difference_nm: [f64; 3],
    /// Largest |replayed - recorded| rendered force, N.
    pub max_force_difference_n: f64,
    /// The algorithm of the replay.
    pub algorithm: String,
    /// Keys of today's configuration the recorded one lacks (recorded before they existed),
    /// replayed with today's defaults: `key = default`.
    pub unrecorded_config: Vec<String>,
    /// What the finger would have felt beyond what was asked, and the jolts, in the replayed
    /// periods (`docs/felt-force.md`).
    pub felt: Option<videt_control::FeltTally>,
}

fn report(log: &Log, r: &Replay, unrecorded: &[UnrecordedKey]) -> ReplayReport {
    let (mut sp, mut tq, mut f) = ([0.0f64; 3], [0.0f64; 3], 0.0f64);
    for (i, out) in &r.replayed {
        let rec = &log.records[*i];
        for w in 0..3 {
            sp[w] = sp[w].max((out.tension_setpoint_n[w] - rec.tension_setpoint_n[w]).abs());
            tq[w] = tq[w].max((out.torque_nm[w] - rec.torque_nm[w]).abs());
        }
        let d: f64 = (0..3)
            .map(|k| (out.rendered_force_n[k] - rec.rendered_force_n[k]).powi(2))
            .sum();
        f = f.max(d.sqrt());
    }
    ReplayReport {
        records: log.records.len(),
        replayed: r.replayed.len(),
        procedure_periods: r.procedure_periods,
        divergent_periods: r.divergent_periods,
        first_divergence: r.first_divergence.as_ref().map(|d| {
            if unrecorded.is_empty() {
                d.to_string()
            } else {
                format!(
                    "{d}; the log was recorded before {} existed: replayed with today's default{} {}",
                    join_keys(unrecorded, |k| k.key.clone()),
                    if unrecorded.len() == 1 { "" } else { "s" },
                    join_keys(unrecorded, |k| k.to_string()),
                )
            }
        }),
        stopped_early: r.stopped_early.clone(),
        damage: log.damage_note(),
        closed: log.closed(),
        end: log.end_note(),
        max_setpoint_difference_n: sp,
        max_torque_difference_nm: tq,
        max_force_difference_n: f,
        algorithm: r.config.control.algorithm.clone(),
        unrecorded_config: unrecorded.iter().map(|k| k.to_string()).collect(),
        felt: crate::felt::felt_report(log, &r.config, r.replayed.iter().map(|(i, o)| (*i, o)))
            .ok(),
    }
}

fn join_keys(keys: &[UnrecordedKey], text: impl Fn(&UnrecordedKey) -> String) -> String {
    keys.iter().map(text).collect::<Vec<_>>().join(", ")
}

/// The recorded and replayed outputs side by side.
pub fn side_by_side_csv(log: &Log, r: &Replay) -> String {
    let mut out = String::from("cycle,time_s");
    let outputs = [
        "tension_setpoint_n",
        "torque_nm",
        "rendered_force_n",
        "desired_force_n",
    ];
    for name in outputs {
        for w in 0..3 {
            let _ = write!(out, ",recorded_{name}_{w},replayed_{name}_{w}");
        }
    }
    out.push_str(",recorded_safety,replayed_safety\n");
    let pick = |r: &CycleRecord, k: usize| match k {
        0 => r.tension_setpoint_n,
        1 => r.torque_nm,
        2 => r.rendered_force_n,
        _ => r.desired_force_n,
    };
    for (i, new) in &r.replayed {
        let old = &log.records[*i];
        let _ = write!(out, "{},{:.9}", old.cycle, old.time.as_secs_f64());
        for k in 0..outputs.len() {
            for w in 0..3 {
                let _ = write!(out, ",{:.9e},{:.9e}", pick(old, k)[w], pick(new, k)[w]);
            }
        }
        let _ = writeln!(out, ",{},{}", old.safety.as_str(), new.safety.as_str());
    }
    out
}

/// Run `videt replay`.
pub fn run(args: &ReplayArgs) -> ToolResult {
    let bytes =
        std::fs::read(&args.logfile).map_err(|e| format!("{}: {e}", args.logfile.display()))?;
    let log = parse_log(&bytes).map_err(|e| format!("{}: {e}", args.logfile.display()))?;
    let overrides = ReplayOverrides {
        config: args
            .config
            .as_deref()
            .map(videt_rt_config::Config::load)
            .transpose()?,
        algorithm: args.algorithm.clone(),
    };
    let r = replay(&log, &overrides).map_err(|e| format!("{}: {e}", args.logfile.display()))?;
    // A configuration given in full replaces the recorded one: nothing of it is missing then.
    let unrecorded = match (&args.config, session_text(&bytes)) {
        (None, Some(text)) => unrecorded_config_keys(text),
        _ => Vec::new(),
    };
    let rep = report(&log, &r, &unrecorded);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print_report(args, &log, &rep, overrides.any());
    }
    let csv = args.csv.clone().or_else(|| {
        overrides.any().then(|| {
            let mut p = args.logfile.clone().into_os_string();
            p.push(".replay.csv");
            PathBuf::from(p)
        })
    });
    if let Some(path) = csv {
        videt_rt_config::calibration::write_atomically(
            &path,
            side_by_side_csv(&log, &r).as_bytes(),
        )
        .map_err(|e| format!("{}: {e}", path.display()))?;
        eprintln!("wrote {}", path.display());
    }
    if let Some(dir) = &args.plot {
        let mut replayed =
            Log::of_records(log.header, r.replayed.iter().map(|(_, out)| *out).collect());
        replayed.surfaces = log.surfaces.clone();
        let limits = super::log_plots::TensionLimits {
            t_min_n: r.config.control.t_min_n,
            t_max_n: r.config.control.t_max_n,
        };
        for path in super::log_plots::write_all(dir, &replayed, limits)? {
            eprintln!("wrote {}", path.display());
        }
        let recorded: Vec<CycleRecord> = r.replayed.iter().map(|(i, _)| log.records[*i]).collect();
        let path = dir.join("replay.png");
        super::log_plots::replay_plot(
            &path,
            &recorded,
            &replayed.records,
            r.first_divergence.as_ref().map(|d| d.time_s),
        )?;
        eprintln!("wrote {}", path.display());
    }
    Ok(if r.identical() || overrides.any() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(EXIT_DIVERGED)
    })
}

fn print_report(args: &ReplayArgs, log: &Log, rep: &ReplayReport, overridden: bool) {
    let what = match &log.session {
        Some(Ok(s)) => s.what.as_str(),
        _ => "",
    };
    println!(
        "{}: replayed {} of {} records ({what}; algorithm {}, {} Hz)",
        args.logfile.display(),
        rep.replayed,
        rep.records,
        rep.algorithm,
        log.header.rate_hz
    );
    if let Some(d) = &rep.damage {
        println!("  {d}");
    }
    if !rep.closed {
        println!("  {}", rep.end);
    }
    if rep.procedure_periods > 0 {
        println!(
            "  {} procedure periods (auto-initialization) skipped: not the control cycle's",
            rep.procedure_periods
        );
    }
    for key in &rep.unrecorded_config {
        match key.split_once(" = ") {
            Some((name, default)) if !name.starts_with('[') => println!(
                "  recorded before {name} existed: replayed with today's default {default}"
            ),
            _ => println!(
                "  recorded before the section {} existed: replayed with today's defaults",
                key.split(' ').next().unwrap_or(key)
            ),
        }
    }
    if let Some(why) = &rep.stopped_early {
        println!("  replay stopped early at {why}");
    }
    if let Some(felt) = &rep.felt {
        println!("  felt force: {felt}");
    }
    match &rep.first_divergence {
        None => println!(
            "  outputs identical to the recorded ones, bit for bit, in every replayed period"
        ),
        Some(d) => {
            println!("  first divergence: {d}");
            println!(
                "  {} of {} periods differ; largest differences: set-points {:.3} / {:.3} / {:.3} N, torques {:.2e} / {:.2e} / {:.2e} N·m, rendered force {:.3} N",
                rep.divergent_periods,
                rep.replayed,
                rep.max_setpoint_difference_n[0],
                rep.max_setpoint_difference_n[1],
                rep.max_setpoint_difference_n[2],
                rep.max_torque_difference_nm[0],
                rep.max_torque_difference_nm[1],
                rep.max_torque_difference_nm[2],
                rep.max_force_difference_n
            );
            if overridden {
                println!("  (other settings: the recorded motion is fed back open-loop; the wearer and the wires would have moved differently)");
            }
        }
    }
}
