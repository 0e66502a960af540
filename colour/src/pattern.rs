//! The vibration pattern of each level: a pure function of time and the level triple.
//!
//! The outputs are on/off (GPIO), so a level is rendered by the duty cycle of a square wave at the
//! carrier frequency (paper §6.1: 75 Hz):
//!
//! | level | default duty | 75 Hz component (relative to High) |
//! |---|---|---|
//! | Low | 0 % (silent) | none |
//! | Mid | 20 % | `sin(0.2π) / sin(0.5π)` = 0.59 (−4.6 dB) |
//! | High | 50 % | 1 (the strongest fundamental a square wave can have) |
//!
//! Why these: the vibrotactor is driven by the switched waveform itself (the HAL says the caller
//! produces the waveform), so what the skin feels is mostly the carrier's fundamental, whose
//! amplitude for duty `d` is `(2/π)·sin(π·d)`. It is largest at 50 %; 100 % would be a constant
//! level with no 75 Hz component at all, so "always on" must not be High. Mid at 20 % is 4.6 dB
//! below High, two to three times the ~1.5–2 dB amplitude difference threshold reported for
//! vibration on the fingertip near this frequency, and carries 40 % of High's mean drive power;
//! Low is silence, which no one confuses with either. A self-oscillating actuator (eccentric-mass
//! motor) would instead want High = 100 % and Mid ≈ 30 %: the duties are configurable.
//!
//! Timing: time is taken modulo an integer period in nanoseconds (`round(1e9 / frequency)`),
//! so the frequency error is below 0.5 ns per period (4·10⁻⁸ at 75 Hz) and no float precision is
//! lost on long uptimes.

use thiserror::Error;
use videt_hal::VIBROTACTORS;

use crate::level::{Level, LevelTriple};

/// A rejected pattern configuration.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("vibration pattern: {field} = {value} is invalid; allowed: {allowed}")]
pub struct PatternConfigError {
    /// The offending field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What is allowed.
    pub allowed: &'static str,
}

/// Carrier frequency and duty per level.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatternConfig {
    /// Carrier frequency, Hz (paper: 75).
    pub frequency_hz: f64,
    /// Fraction of each period the output is on, per level (Low, Mid, High), each in `[0, 1]`,
    /// non-decreasing.
    pub duty: [f64; 3],
}

impl Default for PatternConfig {
    /// 75 Hz; Low silent, Mid 20 %, High 50 % (see the module documentation).
    fn default() -> Self {
        PatternConfig {
            frequency_hz: 75.0,
            duty: [0.0, 0.2, 0.5],
        }
    }
}

/// The pattern generator: validated configuration in integer nanoseconds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pattern {
    period_ns: u64,
    on_ns: [u64; 3],
}

impl Pattern {
    /// Validate and convert a configuration.
    pub fn new(config: PatternConfig) -> Result<Pattern, PatternConfigError> {
        let f = config.frequency_hz;
        if !(f.is_finite() && (1.0..=1000.0).contains(&f)) {
            return Err(PatternConfigError {
                field: "frequency_hz",
                value: f,
                allowed: "1 ..= 1000 Hz",
            });
        }
        let names = ["duty_low", "duty_mid", "duty_high"];
        let mut previous = 0.0;
        for (d, name) in config.duty.iter().zip(names) {
            if !(d.is_finite() && (0.0..=1.0).contains(d)) || *d < previous {
                return Err(PatternConfigError {
                    field: name,
                    value: *d,
                    allowed: "0 ..= 1 and not below the lower level's duty",
                });
            }
            previous = *d;
        }
        let period_ns = (1e9 / f).round() as u64;
        Ok(Pattern {
            period_ns,
            on_ns: config.duty.map(|d| (d * period_ns as f64).round() as u64),
        })
    }

    /// The carrier period, nanoseconds.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// How long a level's output is on in each period, nanoseconds.
    pub fn on_ns(&self, level: Level) -> u64 {
        self.on_ns[level as usize]
    }

    /// Whether a channel at `level` is on at time `t_ns` (periods start at `t_ns = 0 mod period`).
    pub fn is_on(&self, t_ns: u64, level: Level) -> bool {
        t_ns % self.period_ns < self.on_ns[level as usize]
    }

    /// The outputs at `t_ns` for a level triple (all channels in phase).
    pub fn outputs(&self, t_ns: u64, levels: LevelTriple) -> [bool; VIBROTACTORS] {
        let phase = t_ns % self.period_ns;
        levels.map(|l| phase < self.on_ns[l as usize])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use Level::{High as H, Low as L, Mid as M};

    #[test]
    fn duty_per_level_over_one_period() {
        let p = Pattern::new(PatternConfig::default()).unwrap();
        assert_eq!(p.period_ns(), 13_333_333);
        let step = 1_000u64;
        let mut on = [0u64; 3];
        for k in 0..p.period_ns() / step {
            let o = p.outputs(7 * p.period_ns() + k * step, [L, M, H]);
            for c in 0..3 {
                on[c] += u64::from(o[c]);
            }
        }
        let n = (p.period_ns() / step) as f64;
        assert_eq!(on[0], 0);
        assert!((on[1] as f64 / n - 0.2).abs() < 1e-3, "{on:?}");
        assert!((on[2] as f64 / n - 0.5).abs() < 1e-3, "{on:?}");
        assert!(p.is_on(0, H) && !p.is_on(0, L));
    }

    #[test]
    fn bad_configurations_name_the_field() {
        let e = Pattern::new(PatternConfig {
            frequency_hz: 0.0,
            ..PatternConfig::default()
        })
        .unwrap_err();
        assert_eq!(e.field, "frequency_hz");
        let e = Pattern::new(PatternConfig {
            duty: [0.0, 0.6, 0.5],
            ..PatternConfig::default()
        })
        .unwrap_err();
        assert_eq!(e.field, "duty_high");
        let e = Pattern::new(PatternConfig {
            duty: [0.0, 1.2, 1.5],
            ..PatternConfig::default()
        })
        .unwrap_err();
        assert_eq!(e.field, "duty_mid");
        assert!(e.to_string().contains("duty_mid = 1.2"), "{e}");
    }
}
