//! What session logs take on disk: per log, its periods, its bytes per period, and how many
//! times smaller it is than the same log uncompressed, as format version 3 stored it
//! (`videt_runtime::telemetry::version_3_bytes`).
//!
//! `cargo run --release -p videt-tools --example log_size -- LOG.vlog...`

use videt_runtime::telemetry::{version_3_bytes, LogItem, LogReader};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let paths: Vec<String> = std::env::args().skip(1).collect();
    if paths.is_empty() {
        return Err("usage: log_size LOG.vlog...".into());
    }
    println!("log,version,periods,bytes,bytes_per_period,version_3_bytes,times_smaller");
    for path in paths {
        let bytes = std::fs::read(&path)?;
        let reader = LogReader::new(&bytes[..])?;
        let (header, version) = (reader.header(), reader.version());
        let items: Vec<LogItem> = reader.collect();
        let periods = items
            .iter()
            .filter(|i| matches!(i, LogItem::Period(_)))
            .count();
        let v3 = version_3_bytes(&header, items)?.len();
        println!(
            "{path},{version},{periods},{},{:.1},{v3},{:.2}",
            bytes.len(),
            bytes.len() as f64 / periods.max(1) as f64,
            v3 as f64 / bytes.len() as f64
        );
    }
    Ok(())
}
