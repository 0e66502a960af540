//! A long session log made of a short one, to measure what reading an hour of session costs
//! without running the twin for an hour: the short log's periods repeated end to end, their
//! period numbers and times carried on, written as `videtd` writes a log (the same compressed
//! blocks, `videt_runtime::telemetry::write_log`). The session and the calibrations of the short
//! log are kept once; its surfaces are published again in every repetition under new version
//! numbers, as a session keeps publishing them; the end frame says the set duration elapsed.
//!
//! `cargo run --release -p videt-tools --example long_session -- IN.vlog OUT.vlog [MINUTES]`
//! (default 60), then for example `/usr/bin/time -v videt log OUT.vlog --mcap OUT.mcap`.

use std::path::PathBuf;

use videt_runtime::telemetry::{write_log, EndReason, LogItem, LogReader, SessionEnd};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(input), Some(output)) = (args.first(), args.get(1)) else {
        return Err("usage: long_session IN.vlog OUT.vlog [MINUTES]".into());
    };
    let minutes: f64 = args.get(2).map_or(Ok(60.0), |m| m.parse())?;
    let (input, output) = (PathBuf::from(input), PathBuf::from(output));

    // The short log's span and its number of periods, read once.
    let reader = LogReader::open(&input)?;
    let header = reader.header();
    let (mut first, mut last, mut periods, mut versions) = (None, None, 0u64, 0u64);
    for item in reader {
        match item {
            LogItem::Period(r) => {
                first.get_or_insert((r.cycle, r.time.as_nanos()));
                last = Some((r.cycle, r.time.as_nanos()));
                periods += 1;
                versions = versions.max(r.surface_version + 1);
            }
            LogItem::Surface(v, _) => versions = versions.max(v + 1),
            _ => {}
        }
    }
    let (Some((first_cycle, first_ns)), Some((last_cycle, last_ns))) = (first, last) else {
        return Err(format!("{}: no period to repeat", input.display()).into());
    };
    let rate = f64::from(header.rate_hz.max(1));
    let cycles = last_cycle - first_cycle + 1;
    let span_ns = last_ns - first_ns + (1e9 / rate) as u64;
    let repeats = ((minutes * 60.0 * rate) / periods as f64).ceil().max(1.0) as u64;

    // The first pass whole; the later ones their periods only, shifted.
    let pass = |n: u64| -> Result<_, Box<dyn std::error::Error>> {
        Ok(LogReader::open(&input)?.filter_map(move |item| match item {
            LogItem::Period(mut r) => {
                r.cycle += n * cycles;
                r.time.0 += n * span_ns;
                r.surface_version += n * versions;
                Some(LogItem::Period(r))
            }
            LogItem::Surface(v, entry) => Some(LogItem::Surface(v + n * versions, entry)),
            LogItem::End(_) => None,
            other => (n == 0).then_some(other),
        }))
    };
    let passes = (0..repeats).map(pass).collect::<Result<Vec<_>, _>>()?;
    let end = SessionEnd {
        reason: EndReason::DurationElapsed,
        last_cycle: Some(last_cycle + (repeats - 1) * cycles),
        periods: periods * repeats,
        dropped: 0,
    };
    let items = passes
        .into_iter()
        .flatten()
        .chain(std::iter::once(LogItem::End(end)));
    let bytes = write_log(&output, &header, items)?;
    println!(
        "{}: {} periods ({repeats} times {} of {}), {:.1} min, {:.1} MB",
        output.display(),
        periods * repeats,
        periods,
        input.display(),
        (repeats * span_ns) as f64 / 60e9,
        bytes as f64 / 1e6
    );
    Ok(())
}
