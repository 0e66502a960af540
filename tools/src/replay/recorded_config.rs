//! The configuration a replay runs with, and what a log recorded before today's keys lacks.

use videt_config::Config;
use videt_control::Algorithm;
use videt_runtime::telemetry::SessionInfo;

/// Settings that replace the recorded ones.
#[derive(Debug, Clone, Default)]
pub struct ReplayOverrides {
    /// Another configuration for the whole session.
    pub config: Option<Config>,
    /// Another force-distribution algorithm (`control.algorithm`).
    pub algorithm: Option<String>,
}

impl ReplayOverrides {
    /// Whether anything is overridden (outputs are then expected to differ).
    pub fn any(&self) -> bool {
        self.config.is_some() || self.algorithm.is_some()
    }
}

/// A key of today's configuration that a log's recorded configuration lacks (the log was
/// recorded before the key existed): the replay runs with today's default for it, which need
/// not be how the recorded session ran.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnrecordedKey {
    /// The key, dotted (`control.stretch_compensation`).
    pub key: String,
    /// Today's default the replay uses, as TOML.
    pub default: String,
}

impl std::fmt::Display for UnrecordedKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}", self.key, self.default)
    }
}

/// The keys of today's configuration that the recorded session's `[config]` (its TOML text,
/// `LogReader::session_text`) does not have, with the defaults a replay takes for them. A section missing
/// as a whole is named once.
pub fn unrecorded_config_keys(session_toml: &str) -> Vec<UnrecordedKey> {
    fn walk(
        prefix: &str,
        today: &toml::Table,
        recorded: &toml::Table,
        out: &mut Vec<UnrecordedKey>,
    ) {
        for (name, value) in today {
            let key = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}.{name}")
            };
            match (value, recorded.get(name)) {
                (toml::Value::Table(t), Some(toml::Value::Table(r))) => walk(&key, t, r, out),
                (_, Some(_)) => {}
                (toml::Value::Table(_), None) => out.push(UnrecordedKey {
                    key: format!("[{key}]"),
                    default: "(the whole section)".into(),
                }),
                (v, None) => out.push(UnrecordedKey {
                    key,
                    default: v.to_string(),
                }),
            }
        }
    }
    let Ok(session) = session_toml.parse::<toml::Table>() else {
        return Vec::new();
    };
    let Some(toml::Value::Table(recorded)) = session.get("config") else {
        return Vec::new();
    };
    let Ok(today) = toml::Table::try_from(Config::default()) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    walk("", &today, recorded, &mut out);
    out
}

/// The configuration a replay runs with: the recorded one, or the override, with the algorithm
/// override applied.
pub fn replay_config(session: &SessionInfo, overrides: &ReplayOverrides) -> Result<Config, String> {
    let mut config = overrides
        .config
        .clone()
        .unwrap_or_else(|| session.config.clone());
    if let Some(name) = &overrides.algorithm {
        let a = Algorithm::from_name(name).ok_or_else(|| {
            format!(
                "unknown algorithm {name:?}: expected one of {}",
                Algorithm::ALL.map(|a| a.name()).join(", ")
            )
        })?;
        config.control.algorithm = a.name().to_string();
    }
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_missing_from_a_recorded_configuration_are_named_with_their_defaults() {
        let text = SessionInfo::new("twin", Config::default())
            .to_toml()
            .unwrap();
        assert_eq!(unrecorded_config_keys(&text), Vec::new());
        // A log recorded before these keys existed.
        let old: String = text
            .lines()
            .filter(|l| {
                !l.starts_with("stretch_compensation ")
                    && !l.starts_with("tension_integral_speed_gate_m_s ")
            })
            .map(|l| format!("{l}\n"))
            .collect();
        assert_ne!(old.len(), text.len());
        let keys: Vec<String> = unrecorded_config_keys(&old)
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(
            keys,
            [
                "control.stretch_compensation = true",
                "control.tension_integral_speed_gate_m_s = 0.003"
            ]
        );
        // A whole section missing is named once.
        let start = old.find("[config.control]").unwrap();
        let end = start + 1 + old[start + 1..].find("\n[").unwrap();
        let without = format!("{}{}", &old[..start], &old[end + 1..]);
        let keys = unrecorded_config_keys(&without);
        assert_eq!(keys.len(), 1, "{keys:?}");
        assert_eq!(keys[0].key, "[control]");
        assert_eq!(unrecorded_config_keys("not toml ["), Vec::new());
    }
}
