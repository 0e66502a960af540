//! `videt config check FILE`: validate a configuration (ranges, the drives' units against the
//! device description it names, what the configured CAN bus can carry, whether the tension
//! loop is stable on the configured sensor) and print the drives' torque resolution, the bus
//! load, the sensor's timing and the loop's margins, what the session logs keep, and the
//! resolved settings.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Subcommand;
use videt_config::Config;
use videt_runtime::telemetry::retention::{bytes_per_hour, MB};

use super::ToolResult;

/// Configuration subcommands.
#[derive(Debug, Subcommand)]
pub enum ConfigCommand {
    /// Validate FILE; on success print the resolved settings (defaults filled in) as TOML.
    Check {
        /// The configuration file (e.g. /etc/videt/videt.toml).
        file: PathBuf,
    },
}

/// The resolved settings as TOML in the example file's layout (`config/videt.example.toml`): its
/// sections in its order, each setting on one line (arrays inline), a blank line between
/// sections, so a technician can compare the two line by line.
pub fn resolved_settings(config: &Config) -> Result<String, toml::ser::Error> {
    // The non-pretty writer keeps arrays on one line and the settings in the schema's order.
    let text = toml::to_string(config)?;
    // Split into sections: a header line and the lines up to the next top-level header (a
    // sub-table `[a.b]` stays with `[a]`).
    let mut sections: Vec<(String, Vec<&str>)> = Vec::new();
    for line in text.lines() {
        let header = line
            .strip_prefix("[[")
            .or_else(|| line.strip_prefix('['))
            .map(|h| {
                h.trim_end_matches(']')
                    .split('.')
                    .next()
                    .unwrap_or(h)
                    .to_owned()
            });
        match header {
            Some(name) if sections.last().is_none_or(|(last, _)| *last != name) => {
                sections.push((name, vec![line]))
            }
            _ => match sections.last_mut() {
                Some((_, lines)) => lines.push(line),
                None => sections.push((String::new(), vec![line])),
            },
        }
    }
    let layout = example_layout();
    // Stable sorts: what the example lacks keeps its place after what it has.
    sections.sort_by_key(|(name, _)| {
        layout
            .iter()
            .position(|(o, _)| o == name)
            .unwrap_or(layout.len())
    });
    for (name, lines) in &mut sections {
        let Some((_, keys)) = layout.iter().find(|(o, _)| o == name) else {
            continue;
        };
        // The section's own settings, between its header and a sub-table's header if any.
        let end = lines
            .iter()
            .skip(1)
            .position(|l| l.starts_with('['))
            .map_or(lines.len(), |i| i + 1);
        let start = usize::from(lines.first().is_some_and(|l| l.starts_with('[')));
        if start < end {
            lines[start..end].sort_by_key(|l| {
                let key = l.split_once('=').map_or("", |(k, _)| k.trim());
                keys.iter().position(|k| k == key).unwrap_or(keys.len())
            });
        }
    }
    let mut out = String::new();
    for (_, lines) in &sections {
        let lines: Vec<&str> = lines
            .iter()
            .copied()
            .filter(|l| !l.trim().is_empty())
            .collect();
        if lines.is_empty() {
            continue;
        }
        if !out.is_empty() {
            out.push('\n');
        }
        for l in lines {
            out.push_str(l);
            out.push('\n');
        }
    }
    Ok(out)
}

/// The sections of the example configuration and the settings of each, in its order.
fn example_layout() -> Vec<(String, Vec<String>)> {
    let mut layout: Vec<(String, Vec<String>)> = Vec::new();
    for line in crate::manual::EXAMPLE_CONFIG.lines() {
        if let Some(h) = line.strip_prefix('[') {
            layout.push((h.trim_end_matches(']').to_owned(), Vec::new()));
        } else if let (Some((_, keys)), Some((key, _))) = (layout.last_mut(), line.split_once('='))
        {
            if !line.starts_with([' ', '#']) {
                keys.push(key.trim().to_owned());
            }
        }
    }
    layout
}

/// What the session logs keep (`[telemetry]` retention) and how many hours of sessions at the
/// control rate that is.
pub fn describe_retention(config: &Config) -> String {
    let t = &config.telemetry;
    let rate = config.control.rate_hz;
    let per_hour = bytes_per_hour(rate);
    let hours = t.max_total_mb as f64 * MB as f64 / per_hour as f64;
    let kept = format!(
        "kept up to {} MB, {} days, {} MB left free: about {} hours of sessions at {rate} Hz \
         ({:.1} GB per hour)",
        t.max_total_mb,
        t.max_age_days,
        t.min_free_mb,
        if hours < 10.0 {
            format!("{hours:.1}")
        } else {
            format!("{hours:.0}")
        },
        per_hour as f64 / 1e9,
    );
    if t.enabled {
        format!("session logs: {kept}")
    } else {
        format!("session logs: none recorded (telemetry.enabled = false); if enabled, {kept}")
    }
}

/// What the configuration says of the rig's wiring: which drive moves which wire, the
/// reversed motors and encoders, the e-stop's level, the cameras (`videt commission` checks
/// them).
pub fn describe_wiring(config: &Config) -> String {
    let d = &config.drives;
    let wires = |flags: [bool; 3]| {
        let w: Vec<String> = (0..3)
            .filter(|i| flags[*i])
            .map(|i| i.to_string())
            .collect();
        if w.is_empty() {
            "none".to_string()
        } else {
            format!("wire {}", w.join(", "))
        }
    };
    let cells = config.sensors.newtons_per_count.map(|n| n < 0.0);
    format!(
        "wiring: drives of wires 0, 1, 2 at nodes {:?}; motors reversed: {}; encoders reversed: {}; load cells inverted: {}; e-stop pressed at its {} level; cameras left {} right {} (`videt commission` checks them)",
        d.node_ids,
        wires(d.motor_reversed),
        wires(d.encoder_reversed),
        wires(cells),
        config.sensors.estop_pressed_level.name(),
        config.vision.devices[0],
        config.vision.devices[1],
    )
}

/// Run a configuration subcommand.
pub fn run(command: &ConfigCommand) -> ToolResult {
    match command {
        ConfigCommand::Check { file } => {
            let config = Config::load(file)?;
            videt_assembly::bus_budget::check(&config)?;
            videt_runtime::tension_budget::plan(&config)?;
            let resolved = resolved_settings(&config)?;
            println!(
                "# {}: valid\n# {}\n# {}\n# {}\n# {}\n# {}\n{resolved}",
                file.display(),
                videt_assembly::bus_budget::describe(&config),
                videt_runtime::tension_budget::describe(&config),
                config.describe_drive_units(),
                describe_retention(&config),
                describe_wiring(&config),
            );
            Ok(ExitCode::SUCCESS)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `(section, key)` of every setting of a TOML text, in order.
    fn settings(text: &str) -> Vec<(String, String)> {
        let mut section = String::new();
        let mut out = Vec::new();
        for line in text.lines().map(str::trim) {
            if let Some(h) = line.strip_prefix('[') {
                section = h.trim_end_matches(']').to_owned();
            } else if let Some((key, _)) = line.split_once('=') {
                if !line.starts_with('#') {
                    out.push((section.clone(), key.trim().to_owned()));
                }
            }
        }
        out
    }

    #[test]
    fn the_wiring_line_names_every_correction() {
        let mut config = Config::default();
        assert_eq!(
            describe_wiring(&config),
            "wiring: drives of wires 0, 1, 2 at nodes [1, 2, 3]; motors reversed: none; encoders reversed: none; load cells inverted: none; e-stop pressed at its low level; cameras left /dev/video0 right /dev/video2 (`videt commission` checks them)"
        );
        config.drives.motor_reversed = [true, false, true];
        config.sensors.newtons_per_count[1] *= -1.0;
        let line = describe_wiring(&config);
        assert!(line.contains("motors reversed: wire 0, 2;"), "{line}");
        assert!(line.contains("load cells inverted: wire 1;"), "{line}");
    }

    #[test]
    fn the_retention_line_gives_the_limits_and_the_hours_they_hold() {
        let mut config = Config::default();
        // 4096 MB at 210 bytes per period, 1000 periods per second: 5.42 hours.
        assert_eq!(
            describe_retention(&config),
            "session logs: kept up to 4096 MB, 30 days, 1024 MB left free: about 5.4 hours of \
             sessions at 1000 Hz (0.8 GB per hour)"
        );
        config.control.rate_hz = 4000;
        config.telemetry.max_total_mb = 64_000;
        config.telemetry.max_age_days = 7;
        config.telemetry.min_free_mb = 0;
        assert_eq!(
            describe_retention(&config),
            "session logs: kept up to 64000 MB, 7 days, 0 MB left free: about 21 hours of \
             sessions at 4000 Hz (3.0 GB per hour)"
        );
        config.telemetry.enabled = false;
        assert!(
            describe_retention(&config)
                .starts_with("session logs: none recorded (telemetry.enabled = false); if enabled, kept up to 64000 MB"),
            "{}",
            describe_retention(&config)
        );
    }

    #[test]
    fn resolved_settings_read_like_the_example() {
        let example = crate::manual::EXAMPLE_CONFIG;
        let config: Config = toml::from_str(example).unwrap();
        let text = resolved_settings(&config).unwrap();
        // Every setting on one line: no array or table spread over lines.
        for line in text.lines() {
            assert!(
                !line.ends_with('[') && !line.ends_with(','),
                "spread out: {line}\n{text}"
            );
            assert!(!line.starts_with(' '), "indented: {line}\n{text}");
        }
        assert!(
            text.contains("guides_m = [[0.0, 0.0], [0.37, 0.0], [0.185, 0.3]]"),
            "{text}"
        );
        // The sections in the example's order, and each section's settings in its order.
        let headers = |t: &str| -> Vec<String> {
            t.lines()
                .filter(|l| l.starts_with('['))
                .map(str::to_owned)
                .collect()
        };
        assert_eq!(headers(&text), headers(example), "{text}");
        let ours = settings(&text);
        let theirs = settings(example);
        let mut at = 0;
        for s in &theirs {
            let found = ours[at..].iter().position(|o| o == s);
            let Some(i) = found else {
                panic!(
                    "{}.{} missing or out of the example's order in\n{text}",
                    s.0, s.1
                );
            };
            at += i + 1;
        }
        // And it is the configuration it resolves.
        let back: Config = toml::from_str(&text).unwrap();
        assert_eq!(
            toml::to_string(&back).unwrap(),
            toml::to_string(&config).unwrap()
        );
        // Sections apart by one blank line, as in the example.
        assert!(text.contains("\n\n[transmission]\n"), "{text}");
        assert!(!text.contains("\n\n\n"));
    }
}
