//! `videt log LOGFILE`: summarise a session log and export it as CSV or MCAP.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use serde::Serialize;

use videt_runtime::cycle::CycleRecord;
use videt_runtime::histogram::Histogram;
use videt_runtime::telemetry::{
    LogError, LogItem, LogOutline, LogReader, RecordedSurface, SessionInfo, SurfaceEntry,
};

use crate::felt::FeltCounter;
use crate::plot_data::SessionFigureData;

use super::ToolResult;

/// Summarise a telemetry session log (`videtd` writes one per run).
#[derive(Debug, Args)]
pub struct LogArgs {
    /// The session log (`videt-<time>.vlog`).
    pub logfile: PathBuf,
    /// Also export every record as CSV to this file (`-` for standard output).
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Draw the session's figures into this directory (path.png, tensions.png, forces.png,
    /// timing.png).
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
    /// The configuration for the tension limits on the plots (default: the one the session
    /// recorded; for an old log without one, the built-in defaults).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Export the session to this MCAP file for Foxglove or PlotJuggler (the thimble's pose,
    /// the wires, forces and relief as 3D scene, tensions, safety, timing; the configuration
    /// and calibrations attached). Written whole or not at all.
    #[arg(long, value_name = "OUT.mcap")]
    pub mcap: Option<PathBuf>,
    /// Draw a still of what the Foxglove layout (docs/foxglove-layout.json) shows of the
    /// session into this PNG: the 3-D scene, the tensions, the speed and force, the timing and
    /// the safety state, at the moment in contact with the largest desired force (or `--at`).
    #[arg(long, value_name = "OUT.png")]
    pub view_figure: Option<PathBuf>,
    /// With --view-figure: the moment to show, seconds from the session's first period.
    #[arg(long, value_name = "SECONDS", requires = "view_figure")]
    pub at: Option<f64>,
    /// With --mcap: export every N-th period only (safety changes and surfaces are all kept).
    #[arg(long, value_name = "N", default_value_t = 1, requires = "mcap",
          value_parser = clap::value_parser!(u32).range(1..))]
    pub every: u32,
}

/// The summary of a log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LogSummary {
    /// Control rate, Hz.
    pub rate_hz: u32,
    /// Records in the file.
    pub records: usize,
    /// Seconds covered.
    pub duration_s: f64,
    /// Records missing (gaps in the cycle numbers: dropped by a full ring).
    pub dropped: u64,
    /// Bytes of a cut-off last record.
    pub truncated_bytes: usize,
    /// The session closed its log (an end frame).
    pub closed: bool,
    /// How the session ended: as the end frame says, or that it ended without closing.
    pub end: String,
    /// Wake-up latency percentiles, µs: p50, p99, p99.9, max.
    pub wake_latency_us: [f64; 4],
    /// Compute time percentiles, µs: p50, p99, p99.9, max.
    pub compute_us: [f64; 4],
    /// Fraction of periods in contact.
    pub contact_fraction: f64,
    /// Largest measured tension, N.
    pub max_tension_n: f64,
    /// Largest rendered force, N.
    pub max_force_n: f64,
    /// Safety transitions: (time in s, new state).
    pub safety_events: Vec<(f64, String)>,
    /// Frame to force: from a camera frame's capture to the first period rendering the relief
    /// built from it (`None` when no rendered surface came from a camera frame).
    pub frame_to_force: Option<FrameToForce>,
    /// What the finger felt beyond what was asked, and the jolts (`docs/felt-force.md`);
    /// `None` when the configuration names no device the tools know.
    pub felt: Option<videt_control::FeltTally>,
}

/// Latency from camera frames to the control thread, over the surface versions rendered.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameToForce {
    /// Versions built from a camera frame and rendered.
    pub frames: usize,
    /// Median, ms.
    pub p50_ms: f64,
    /// 99th percentile, ms (nearest rank).
    pub p99_ms: f64,
    /// Largest, ms.
    pub max_ms: f64,
}

impl FrameToForce {
    /// The latency of the periods that first rendered a version made from a camera frame.
    pub fn of(records: &[CycleRecord]) -> Option<FrameToForce> {
        FrameToForce::of_ages(
            records
                .iter()
                .filter_map(|r| r.inputs.surface_frame_age_ns)
                .collect(),
        )
    }

    /// The latency over these frame ages, ns.
    pub fn of_ages(mut ages: Vec<u64>) -> Option<FrameToForce> {
        if ages.is_empty() {
            return None;
        }
        ages.sort_unstable();
        let rank =
            |q: f64| ages[((q * ages.len() as f64).ceil() as usize).clamp(1, ages.len()) - 1];
        Some(FrameToForce {
            frames: ages.len(),
            p50_ms: rank(0.5) as f64 * 1e-6,
            p99_ms: rank(0.99) as f64 * 1e-6,
            max_ms: ages[ages.len() - 1] as f64 * 1e-6,
        })
    }
}

fn percentiles_us(h: &Histogram) -> [f64; 4] {
    [
        h.quantile_ns(0.5),
        h.quantile_ns(0.99),
        h.quantile_ns(0.999),
        h.max_ns(),
    ]
    .map(|ns| ns as f64 * 1e-3)
}

/// The summary's tallies, period by period.
#[derive(Default)]
struct Tallies {
    wake: Histogram,
    compute: Histogram,
    dropped: u64,
    contact: usize,
    max_tension: f64,
    max_force: f64,
    events: Vec<(f64, String)>,
    last_state: Option<videt_control::SafetyState>,
    last_cycle: Option<u64>,
    frame_ages: Vec<u64>,
}

impl Tallies {
    fn add(&mut self, r: &CycleRecord) {
        if let Some(last) = self.last_cycle {
            self.dropped += r.cycle.saturating_sub(last.saturating_add(1));
        }
        self.last_cycle = Some(r.cycle);
        self.wake.record(r.wake_latency_ns);
        self.compute.record(r.compute_ns);
        self.contact += usize::from(r.in_contact);
        self.max_tension = r
            .tension_measured_n
            .iter()
            .cloned()
            .fold(self.max_tension, f64::max);
        let f = r.rendered_force_n;
        self.max_force = self
            .max_force
            .max((f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt());
        if self.last_state != Some(r.safety) {
            if self.last_state.is_some() || r.safety.reason().is_some() {
                self.events
                    .push((r.time.as_secs_f64(), r.safety.as_str().to_string()));
            }
            self.last_state = Some(r.safety);
        }
        self.frame_ages.extend(r.inputs.surface_frame_age_ns);
    }
}

/// What one pass over a log gathers for `videt log`.
pub struct Summarised {
    /// The summary.
    pub summary: LogSummary,
    /// The outline.
    pub outline: LogOutline,
    /// The configuration the session ran (or `--config`).
    pub config: videt_config::Config,
    /// What the figures draw (with `--plot`).
    pub figures: Option<SessionFigureData>,
}

/// Summarise `args.logfile`, read once as a stream (the memory it takes does not grow with the
/// session's length); returns the summary, the log's outline, the configuration the session
/// ran (`--config` when given) and, with `--plot`, what the figures draw.
pub fn summarise(args: &LogArgs) -> Result<Summarised, super::ToolError> {
    let explicit = args
        .config
        .as_deref()
        .map(videt_config::Config::load)
        .transpose()?;
    let mut reader = LogReader::open(&args.logfile)?;
    let mut outline = LogOutline::new(reader.header(), reader.version());
    let mut tallies = Tallies::default();
    let mut felt: Option<Result<FeltCounter, String>> = None;
    let mut figures = args.plot.as_ref().map(|_| SessionFigureData::default());
    for item in &mut reader {
        outline.add(&item);
        let counted = matches!(item, LogItem::Period(_) | LogItem::Calibration { .. });
        // Made at the first calibration or period: the session frame comes before either.
        if counted && felt.is_none() {
            let config = session_config(explicit.as_ref(), outline.session.as_ref());
            felt = Some(FeltCounter::new(&config));
        }
        let counter = felt.as_mut().and_then(|c| c.as_mut().ok());
        match &item {
            LogItem::Period(r) => {
                tallies.add(r);
                if let Some(f) = figures.as_mut() {
                    f.add(r);
                }
                if let Some(c) = counter {
                    c.period(r);
                }
            }
            LogItem::Calibration { calibration, .. } => {
                if let Some(c) = counter {
                    c.calibration(calibration);
                }
            }
            _ => {}
        }
    }
    outline.finish(&reader);
    let config = session_config(explicit.as_ref(), outline.session.as_ref());
    let records = outline.records;
    let summary = LogSummary {
        rate_hz: outline.header.rate_hz,
        records,
        duration_s: outline.duration_s(),
        dropped: tallies.dropped,
        truncated_bytes: outline.truncated_bytes as usize,
        closed: outline.closed(),
        end: outline.end_note.clone(),
        wake_latency_us: percentiles_us(&tallies.wake),
        compute_us: percentiles_us(&tallies.compute),
        contact_fraction: if records == 0 {
            0.0
        } else {
            tallies.contact as f64 / records as f64
        },
        max_tension_n: tallies.max_tension,
        max_force_n: tallies.max_force,
        safety_events: tallies.events,
        frame_to_force: FrameToForce::of_ages(tallies.frame_ages),
        felt: felt.and_then(|c| c.ok()).and_then(|c| c.finish().ok()),
    };
    Ok(Summarised {
        summary,
        outline,
        config,
        figures,
    })
}

/// Write the records as CSV.
pub fn write_csv(
    records: impl IntoIterator<Item = CycleRecord>,
    out: &mut dyn Write,
) -> std::io::Result<()> {
    let mut header = String::from("cycle,time_s,wake_latency_us,compute_us");
    for name in CycleRecord::VECTOR_NAMES {
        for axis in 0..3 {
            header.push_str(&format!(",{name}_{axis}"));
        }
    }
    header.push_str(
        ",contact,depth_m,force_scale,surface_version,surface_stale,safety,released_wire,frame_age_ms",
    );
    writeln!(out, "{header}")?;
    for r in records {
        write!(
            out,
            "{},{:.9},{:.3},{:.3}",
            r.cycle,
            r.time.as_secs_f64(),
            r.wake_latency_ns as f64 * 1e-3,
            r.compute_ns as f64 * 1e-3
        )?;
        for arr in r.vectors() {
            for v in arr {
                write!(out, ",{v:.6e}")?;
            }
        }
        write!(
            out,
            ",{},{:.6e},{:.4},{},{},{},{},",
            u8::from(r.in_contact),
            r.contact_depth_m,
            r.force_scale,
            r.surface_version,
            u8::from(r.surface_stale),
            r.safety.as_str(),
            r.released_wire
        )?;
        // Empty but on the first period rendering a version made from a camera frame.
        match r.inputs.surface_frame_age_ns {
            Some(ns) => writeln!(out, "{:.3}", ns as f64 * 1e-6)?,
            None => writeln!(out)?,
        }
    }
    Ok(())
}

/// The configuration the session ran: `explicit` (`--config`) when given, else the one it
/// recorded, else (an old log without one) the built-in defaults.
fn session_config(
    explicit: Option<&videt_config::Config>,
    session: Option<&Result<SessionInfo, String>>,
) -> videt_config::Config {
    match (explicit, session) {
        (Some(config), _) => config.clone(),
        (None, Some(Ok(session))) => session.config.clone(),
        (None, _) => videt_config::Config::default(),
    }
}

/// The surface `version` as `path` recorded it (`None`: published but not recorded, or not in
/// the log), read as a stream up to it.
pub fn recorded_surface(
    path: &std::path::Path,
    version: u64,
) -> Result<Option<std::sync::Arc<RecordedSurface>>, LogError> {
    for item in LogReader::open(path)? {
        if let LogItem::Surface(v, entry) = item {
            match entry {
                SurfaceEntry::Recorded(s) if v == version => return Ok(Some(s)),
                _ if v >= version => return Ok(None),
                _ => {}
            }
        }
    }
    Ok(None)
}

/// The records of `path`, read as a stream.
fn records(path: &std::path::Path) -> Result<impl Iterator<Item = CycleRecord>, LogError> {
    Ok(LogReader::open(path)?.filter_map(|item| match item {
        LogItem::Period(r) => Some(r),
        _ => None,
    }))
}

/// Run `videt log`.
pub fn run(args: &LogArgs) -> ToolResult {
    let Summarised {
        summary: s,
        outline,
        config,
        figures,
    } = summarise(args)?;
    if let Some(out) = &args.view_figure {
        let shown = super::view_figure::write_view_figure(out, &args.logfile, &config, args.at)?;
        eprintln!("wrote {} (the session at {shown:.3} s)", out.display());
    }
    if let (Some(dir), Some(figures)) = (&args.plot, &figures) {
        let limits = super::log_plots::TensionLimits {
            t_min_n: config.control.t_min_n,
            t_max_n: config.control.t_max_n,
        };
        let surface = match figures.session_surface_version() {
            Some(version) => recorded_surface(&args.logfile, version)?.map(|s| (version, s)),
            None => None,
        };
        let surface = surface.as_ref().map(|(v, s)| (*v, s.as_ref()));
        for path in super::log_plots::write_all(dir, figures, surface, limits)? {
            eprintln!("wrote {}", path.display());
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&s)?);
    } else {
        println!(
            "{}: {} records at {} Hz, {:.3} s",
            args.logfile.display(),
            s.records,
            s.rate_hz,
            s.duration_s
        );
        println!("  dropped records: {}", s.dropped);
        if let Some(note) = &outline.damage_note {
            println!("  {note}");
        }
        println!("  {}", s.end);
        match &outline.session {
            Some(Ok(session)) => println!(
                "  session: {} (videtd {}, algorithm {})",
                session.what, session.videt_version, session.config.control.algorithm
            ),
            Some(Err(e)) => println!("  session: {e}"),
            None => println!(
                "  session: not recorded (format version {})",
                outline.version
            ),
        }
        if !outline.surfaces.is_empty() {
            let lost = outline.lost_surfaces().len();
            let recorded = outline.surfaces.len() - lost;
            println!(
                "  surfaces: {recorded} version{} recorded{}, {} rendered by the periods",
                if recorded == 1 { "" } else { "s" },
                if lost > 0 {
                    format!(" ({lost} lost)")
                } else {
                    String::new()
                },
                outline.first_render_ns.len()
            );
        }
        let p = |v: [f64; 4]| {
            format!(
                "p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1} µs",
                v[0], v[1], v[2], v[3]
            )
        };
        println!("  wake-up latency: {}", p(s.wake_latency_us));
        println!("  compute time:    {}", p(s.compute_us));
        if let Some(f) = &s.frame_to_force {
            println!(
                "  frame to force:  p50 {:.2}  p99 {:.2}  max {:.2} ms over {} camera frames (capture to first render)",
                f.p50_ms, f.p99_ms, f.max_ms, f.frames
            );
        }
        println!(
            "  in contact {:.1}% of the time; max tension {:.2} N; max force {:.2} N",
            100.0 * s.contact_fraction,
            s.max_tension_n,
            s.max_force_n
        );
        if let Some(felt) = &s.felt {
            println!("  felt force: {felt}");
        }
        if s.safety_events.is_empty() {
            println!("  safety: normal throughout");
        }
        for (t, state) in &s.safety_events {
            println!("  safety at {t:.3} s: {state}");
        }
    }
    if let Some(out) = &args.mcap {
        export_mcap(args, outline.records, out)?;
    }
    if let Some(csv) = &args.csv {
        if csv.as_os_str() == "-" {
            write_csv(records(&args.logfile)?, &mut std::io::stdout().lock())?;
        } else {
            let mut out = std::io::BufWriter::new(std::fs::File::create(csv)?);
            write_csv(records(&args.logfile)?, &mut out)?;
            out.flush()?;
            if !args.json {
                println!("  CSV written to {}", csv.display());
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Export `args.logfile` (of `records` periods) to `out` as MCAP, read as a stream, with a
/// progress bar on a terminal and a one-line summary.
fn export_mcap(
    args: &LogArgs,
    records: usize,
    out: &std::path::Path,
) -> Result<(), super::ToolError> {
    use videt_viewers::mcap_export::{export_mcap_file, ExportOptions};

    // On standard error, drawn only when it is a terminal.
    let bar = indicatif::ProgressBar::new(records as u64).with_style(
        indicatif::ProgressStyle::with_template("MCAP [{bar:40}] {percent:>3}% {pos}/{len}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar())
            .progress_chars("#> "),
    );
    let summary = export_mcap_file(
        &args.logfile,
        out,
        &ExportOptions { every: args.every },
        |done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
        },
    );
    bar.finish_and_clear();
    let s = summary?;
    for note in &s.notes {
        eprintln!("videt: {}: {note}", out.display());
    }
    let line = format!(
        "MCAP written to {}: {} periods, {} messages, {} surface version{}, {} bytes ({:.1} MiB), {:.3} s of session, converted in {:.2} s",
        s.path.display(),
        s.periods,
        s.messages,
        s.surfaces,
        if s.surfaces == 1 { "" } else { "s" },
        s.bytes,
        s.bytes as f64 / (1024.0 * 1024.0),
        s.session_s,
        s.elapsed_s
    );
    // With --json, standard output holds the JSON alone.
    if args.json {
        eprintln!("{line}");
    } else {
        println!("  {line}");
    }
    Ok(())
}
