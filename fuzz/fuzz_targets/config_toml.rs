//! Fuzzes the configuration file: arbitrary text through `Config::from_toml_str_at` (what
//! `Config::from_toml_str` and `Config::load` run): TOML parsing, the units of a named drive
//! description and every validation rule. A `drives.device_description` is resolved against the
//! committed EDS/DCF seeds (`seeds/eds_parse/`), so a plain file name reads a real drive sheet;
//! inputs naming any other path (absolute, or with a directory) are skipped, so the target never
//! reads arbitrary files of the machine (a device node would block it).
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use videt_config::Config;

const EDS_DIR: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/seeds/eds_parse");

/// Whether the description the text names, if any, is a file name inside [`EDS_DIR`].
fn description_stays_in_seeds(text: &str) -> bool {
    let Ok(table) = text.parse::<toml::Table>() else {
        // Not TOML: the configuration parser refuses it before reading any file.
        return true;
    };
    let named = table
        .get("drives")
        .and_then(|d| d.as_table())
        .and_then(|d| d.get("device_description"));
    match named.and_then(|v| v.as_str()) {
        None => true,
        Some(name) => !name.contains(['/', '\\', '\0']) && !name.starts_with('.'),
    }
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if !description_stays_in_seeds(text) {
        return;
    }
    if let Ok(config) = Config::from_toml_str_at(text, "fuzz.toml", Some(Path::new(EDS_DIR))) {
        // What the service derives from an accepted configuration must not panic either.
        let _ = format!("{config:?}");
    }
});
