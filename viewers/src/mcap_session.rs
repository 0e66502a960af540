//! The session's records in an MCAP export: its metadata (`videt.session`), the recorded
//! configuration and each calibration as attachments and metadata.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::io::{Seek, Write};

use foxglove::McapAttachment;
use videt_runtime::telemetry::{CalibrationEntry, LogOutline};

use crate::topics::SceneSetup;

/// The session's metadata, the configuration and the calibrations.
pub(crate) fn write_session_records<W: Write + Seek + Send + 'static>(
    outline: &LogOutline,
    config_toml: Option<String>,
    setup: &SceneSetup,
    start_ns: u64,
    mcap: &foxglove::McapWriterHandle<W>,
) -> Result<(), foxglove::FoxgloveError> {
    let mut meta = BTreeMap::new();
    let mut put = |k: &str, v: String| {
        meta.insert(k.to_string(), v);
    };
    put("format_version", outline.version.to_string());
    put("rate_hz", outline.header.rate_hz.to_string());
    put("start_unix_ns", outline.header.start_unix_ns.to_string());
    put("first_record_monotonic_ns", start_ns.to_string());
    put(
        "clock",
        "log times are the service's monotonic clock, ns; start_unix_ns is the wall-clock start"
            .into(),
    );
    put("records", outline.records.to_string());
    put("device", setup.device.clone());
    put("wires", setup.wires.to_string());
    put(
        "guides_m",
        serde_json::to_string(&setup.guides_m).unwrap_or_default(),
    );
    put("calibrations", outline.calibrations.len().to_string());
    match &outline.session {
        Some(Ok(s)) => {
            put("videt_version", s.videt_version.clone());
            put("what", s.what.clone());
            put("algorithm", s.config.control.algorithm.to_string());
        }
        Some(Err(e)) => put("session", format!("unreadable: {e}")),
        None => put("session", "not recorded".into()),
    }
    if let Some(note) = &outline.damage_note {
        put("damage", note.clone());
    }
    put("closed", outline.closed().to_string());
    put("end", outline.end_note.clone());
    mcap.write_metadata("videt.session", meta)?;

    if let Some(text) = config_toml {
        mcap.attach(&McapAttachment {
            log_time: start_ns,
            create_time: start_ns,
            name: "config.toml".into(),
            media_type: "application/toml".into(),
            data: Cow::Owned(text.into_bytes()),
        })?;
    }
    for (n, c) in outline.calibrations.iter().enumerate() {
        let time = c.time_ns.or(outline.last_ns).unwrap_or(start_ns);
        let json = calibration_json(&c.entry);
        mcap.attach(&McapAttachment {
            log_time: time,
            create_time: time,
            name: format!("calibration-{n}.json"),
            media_type: "application/json".into(),
            data: Cow::Owned(json.clone().into_bytes()),
        })?;
        let mut meta = BTreeMap::new();
        meta.insert("calibration".to_string(), json);
        mcap.write_metadata(&format!("videt.calibration.{n}"), meta)?;
    }
    Ok(())
}

fn calibration_json(entry: &CalibrationEntry) -> String {
    let c = &entry.calibration;
    let value = serde_json::json!({
        "from_cycle": entry.from_cycle,
        "before_record": entry.before_record,
        "calibrated": c.calibrated,
        "guides_m": c.guides_m,
        "length_at_zero_m": c.length_at_zero_m,
    });
    serde_json::to_string_pretty(&value).unwrap_or_default()
}
