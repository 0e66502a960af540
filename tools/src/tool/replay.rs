//! `videt replay LOG`: re-run a recorded session through the same control cycle code and
//! compare every output with the recorded one; with `--config`/`--algorithm`, what other
//! settings would have commanded along the same session.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::Args;
use serde::Serialize;

use crate::felt::FeltCounter;
use crate::plot_data::{norm, Decimator, DrawnPeriod, SessionFigureData};
use crate::replay::{
    replay_items, unrecorded_config_keys, ReplayObserver, ReplayOutcome, ReplayOverrides,
    UnrecordedKey,
};
use videt_runtime::cycle::CycleRecord;
use videt_runtime::telemetry::{CalibrationInForce, LogReader};

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

/// The largest differences between replayed and recorded outputs.
#[derive(Debug, Default)]
struct Differences {
    setpoint_n: [f64; 3],
    torque_nm: [f64; 3],
    force_n: f64,
}

impl Differences {
    fn add(&mut self, rec: &CycleRecord, out: &CycleRecord) {
        for w in 0..3 {
            let sp = (out.tension_setpoint_n[w] - rec.tension_setpoint_n[w]).abs();
            self.setpoint_n[w] = self.setpoint_n[w].max(sp);
            let tq = (out.torque_nm[w] - rec.torque_nm[w]).abs();
            self.torque_nm[w] = self.torque_nm[w].max(tq);
        }
        let d: f64 = (0..3)
            .map(|k| (out.rendered_force_n[k] - rec.rendered_force_n[k]).powi(2))
            .sum();
        self.force_n = self.force_n.max(d.sqrt());
    }
}

/// The recorded and replayed outputs side by side, written as the replay runs to a temporary
/// file beside the destination that takes its place when complete (and is removed otherwise).
struct SideBySideCsv {
    path: PathBuf,
    out: std::io::BufWriter<tempfile::NamedTempFile>,
    error: Option<std::io::Error>,
}

const CSV_OUTPUTS: [&str; 4] = [
    "tension_setpoint_n",
    "torque_nm",
    "rendered_force_n",
    "desired_force_n",
];

impl SideBySideCsv {
    fn create(path: &Path) -> Result<SideBySideCsv, String> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let file =
            tempfile::NamedTempFile::new_in(dir).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut csv = SideBySideCsv {
            path: path.to_path_buf(),
            out: std::io::BufWriter::new(file),
            error: None,
        };
        csv.write(|out| {
            write!(out, "cycle,time_s")?;
            for name in CSV_OUTPUTS {
                for w in 0..3 {
                    write!(out, ",recorded_{name}_{w},replayed_{name}_{w}")?;
                }
            }
            writeln!(out, ",recorded_safety,replayed_safety")
        });
        Ok(csv)
    }

    /// Write with `f`, unless a write failed before; the first error is kept.
    fn write(&mut self, f: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>) {
        if self.error.is_none() {
            if let Err(e) = f(&mut self.out) {
                self.error = Some(e);
            }
        }
    }

    fn period(&mut self, old: &CycleRecord, new: &CycleRecord) {
        let pick = |r: &CycleRecord, k: usize| match k {
            0 => r.tension_setpoint_n,
            1 => r.torque_nm,
            2 => r.rendered_force_n,
            _ => r.desired_force_n,
        };
        self.write(|out| {
            write!(out, "{},{:.9}", old.cycle, old.time.as_secs_f64())?;
            for k in 0..CSV_OUTPUTS.len() {
                for w in 0..3 {
                    write!(out, ",{:.9e},{:.9e}", pick(old, k)[w], pick(new, k)[w])?;
                }
            }
            writeln!(out, ",{},{}", old.safety.as_str(), new.safety.as_str())
        });
    }

    /// Flush, sync and put the file in place.
    fn finish(self) -> Result<PathBuf, String> {
        let SideBySideCsv { path, out, error } = self;
        let placed = match error {
            Some(e) => Err(e),
            None => out
                .into_inner()
                .map_err(|e| e.into_error())
                .and_then(|f| f.as_file().sync_all().map(|()| f))
                .and_then(|f| f.persist(&path).map_err(|e| e.error)),
        };
        placed
            .map(|_| path.clone())
            .map_err(|e| format!("{}: {e}", path.display()))
    }
}

/// What the figures of a replay draw: the replayed session's, and the recorded and replayed
/// outputs side by side.
struct ReplayFigures {
    replayed: SessionFigureData,
    pairs: Decimator<(DrawnPeriod, DrawnPeriod), 8>,
}

/// What `videt replay` gathers as the replay runs: the differences, the felt force, the CSV
/// and the figures, none of which keeps the periods.
struct Gathered {
    differences: Differences,
    felt: Option<Result<FeltCounter, String>>,
    csv: Option<SideBySideCsv>,
    figures: Option<ReplayFigures>,
}

impl ReplayObserver for Gathered {
    fn session(&mut self, config: &videt_config::Config) {
        self.felt = Some(FeltCounter::new(config));
    }

    fn calibration(&mut self, calibration: &CalibrationInForce) {
        if let Some(Ok(felt)) = self.felt.as_mut() {
            felt.calibration(calibration);
        }
    }

    fn period(&mut self, _index: usize, recorded: &CycleRecord, replayed: &CycleRecord) {
        self.differences.add(recorded, replayed);
        if let Some(Ok(felt)) = self.felt.as_mut() {
            felt.period(replayed);
        }
        if let Some(csv) = self.csv.as_mut() {
            csv.period(recorded, replayed);
        }
        if let Some(f) = self.figures.as_mut() {
            f.replayed.add(replayed);
            let (a, b) = (DrawnPeriod::of(recorded), DrawnPeriod::of(replayed));
            f.pairs.add(
                a.time_s,
                (a, b),
                [
                    Some(a.tension_setpoint_n[0]),
                    Some(b.tension_setpoint_n[0]),
                    Some(a.tension_setpoint_n[1]),
                    Some(b.tension_setpoint_n[1]),
                    Some(a.tension_setpoint_n[2]),
                    Some(b.tension_setpoint_n[2]),
                    Some(norm(a.rendered_force_n)),
                    Some(norm(b.rendered_force_n)),
                ],
            );
        }
    }
}

fn report(
    reader: &LogReader<std::io::BufReader<std::fs::File>>,
    r: &ReplayOutcome,
    gathered: &mut Gathered,
    unrecorded: &[UnrecordedKey],
) -> ReplayReport {
    let d = &gathered.differences;
    ReplayReport {
        records: r.records,
        replayed: r.replayed,
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
        damage: reader.damage_note(),
        closed: reader.closed(),
        end: reader.end_note(),
        max_setpoint_difference_n: d.setpoint_n,
        max_torque_difference_nm: d.torque_nm,
        max_force_difference_n: d.force_n,
        algorithm: r.config.control.algorithm.clone(),
        unrecorded_config: unrecorded.iter().map(|k| k.to_string()).collect(),
        felt: gathered
            .felt
            .take()
            .and_then(|c| c.ok())
            .and_then(|c| c.finish().ok()),
    }
}

fn join_keys(keys: &[UnrecordedKey], text: impl Fn(&UnrecordedKey) -> String) -> String {
    keys.iter().map(text).collect::<Vec<_>>().join(", ")
}

/// Run `videt replay`.
pub fn run(args: &ReplayArgs) -> ToolResult {
    let named = |e: &dyn std::fmt::Display| format!("{}: {e}", args.logfile.display());
    let mut reader = LogReader::open(&args.logfile).map_err(|e| named(&e))?;
    let overrides = ReplayOverrides {
        config: args
            .config
            .as_deref()
            .map(videt_config::Config::load)
            .transpose()?,
        algorithm: args.algorithm.clone(),
    };
    let csv = args.csv.clone().or_else(|| {
        overrides.any().then(|| {
            let mut p = args.logfile.clone().into_os_string();
            p.push(".replay.csv");
            PathBuf::from(p)
        })
    });
    let mut gathered = Gathered {
        differences: Differences::default(),
        felt: None,
        csv: csv.as_deref().map(SideBySideCsv::create).transpose()?,
        figures: args.plot.as_ref().map(|_| ReplayFigures {
            replayed: SessionFigureData::default(),
            pairs: Decimator::new(),
        }),
    };
    let (version, rate_hz) = (reader.version(), reader.header().rate_hz);
    let r = replay_items(version, &mut reader, &overrides, &mut gathered);
    // On an error the CSV's temporary file goes with it.
    let r = r.map_err(|e| named(&e))?;
    // A configuration given in full replaces the recorded one: nothing of it is missing then.
    let unrecorded = match (&args.config, reader.session_text()) {
        (None, Some(text)) => unrecorded_config_keys(text),
        _ => Vec::new(),
    };
    let rep = report(&reader, &r, &mut gathered, &unrecorded);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rep)?);
    } else {
        print_report(args, &r.what, rate_hz, &rep, overrides.any());
    }
    if let Some(csv) = gathered.csv.take() {
        eprintln!("wrote {}", csv.finish()?.display());
    }
    if let (Some(dir), Some(figures)) = (&args.plot, &gathered.figures) {
        let limits = super::log_plots::TensionLimits {
            t_min_n: r.config.control.t_min_n,
            t_max_n: r.config.control.t_max_n,
        };
        let surface = match figures.replayed.session_surface_version() {
            Some(version) => {
                super::log::recorded_surface(&args.logfile, version)?.map(|s| (version, s))
            }
            None => None,
        };
        let surface = surface.as_ref().map(|(v, s)| (*v, s.as_ref()));
        for path in super::log_plots::write_all(dir, &figures.replayed, surface, limits)? {
            eprintln!("wrote {}", path.display());
        }
        let path = dir.join("replay.png");
        super::log_plots::replay_plot(
            &path,
            &figures.pairs.kept(),
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

fn print_report(args: &ReplayArgs, what: &str, rate_hz: u32, rep: &ReplayReport, overridden: bool) {
    println!(
        "{}: replayed {} of {} records ({what}; algorithm {}, {} Hz)",
        args.logfile.display(),
        rep.replayed,
        rep.records,
        rep.algorithm,
        rate_hz
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
