//! What the configured tension sensor can feed: its conversions' timing, the PI tension loop's
//! margins on it, and the refusal (or the explicit degraded mode) of a sensor too slow for the
//! configured gains.
//!
//! Converters (their timing, [`ConverterModel`], is what the twin simulates too): the HX711 at 10 or 80
//! samples/s settles in 4 conversions (its datasheet: 400 ms / 50 ms); the ADS1220 in normal or
//! turbo mode, its sinc3 filter settling in 3; a drive's analog input is read at every SYNC (its
//! own input filter is not modelled). The loop's margins come from
//! [`videt_control::tension_loop`].

use videt_config::{Ads1220Mode, Config, ConfigError, TensionAdc};
use videt_control::tension_loop::{
    loop_delay_s, pi_margins, stable_gain_scale, LoopMargins, MIN_GAIN_MARGIN, MIN_PHASE_MARGIN_DEG,
};
use videt_hal::ConverterModel;

/// The timing of the configured converters, for the twin and for the checks.
pub fn converter_model(config: &Config) -> ConverterModel {
    let s = &config.sensors;
    let (rate, order) = match s.adc {
        TensionAdc::Hx711 => (f64::from(s.sample_rate_sps), 4),
        TensionAdc::Ads1220 => (f64::from(s.sample_rate_sps), 3),
        TensionAdc::Drive => (f64::from(config.control.rate_hz), 0),
    };
    ConverterModel {
        sample_rate_sps: rate,
        filter_order: order,
        newtons_per_count: s.newtons_per_count[0].abs(),
    }
}

/// The converter's name as configured.
fn converter_name(config: &Config) -> String {
    let s = &config.sensors;
    match s.adc {
        TensionAdc::Hx711 => format!("HX711 at {} samples/s", s.sample_rate_sps),
        TensionAdc::Ads1220 => format!(
            "ADS1220 at {} samples/s ({} mode)",
            s.sample_rate_sps,
            match s.ads1220_mode {
                Ads1220Mode::Normal => "normal",
                Ads1220Mode::Turbo => "turbo",
            }
        ),
        TensionAdc::Drive => "the drives' analog inputs, read at every SYNC".to_string(),
    }
}

/// How the tension loop runs on the configured sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TensionLoopPlan {
    /// With the configured gains.
    Full(LoopMargins),
    /// With the configured gains times `scale` (`control.allow_degraded_tension_loop`).
    Degraded {
        /// The fraction of both gains.
        scale: f64,
        /// The margins with the configured gains.
        configured: LoopMargins,
        /// The margins with the reduced gains.
        reduced: LoopMargins,
    },
}

impl TensionLoopPlan {
    /// The fraction of the configured PI gains the loop runs with.
    pub fn gain_scale(&self) -> f64 {
        match self {
            TensionLoopPlan::Full(_) => 1.0,
            TensionLoopPlan::Degraded { scale, .. } => *scale,
        }
    }
}

/// The delay of the tension measurement in the loop, seconds.
pub fn loop_delay(config: &Config) -> f64 {
    let m = converter_model(config);
    loop_delay_s(
        m.group_delay_s(),
        m.period_s(),
        1.0 / f64::from(config.control.rate_hz.max(1)),
    )
}

/// Newtons of tension per newton-metre of motor torque (the loop's plant gain).
fn plant_gain(config: &Config) -> f64 {
    1.0 / crate::drive_train::transmission(config).torque_for_tension(1.0)
}

/// Decide how the tension loop runs on the configured sensor, or refuse the configuration:
/// a staleness limit the converter cannot meet, a loop unstable at the configured gains
/// (unless `control.allow_degraded_tension_loop`), or one no useful gain keeps stable.
pub fn plan(config: &Config) -> Result<TensionLoopPlan, ConfigError> {
    let m = converter_model(config);
    let c = &config.control;
    let s = &config.sensors;
    let period_ms = 1e3 * m.period_s();
    if config.sensors.adc != TensionAdc::Drive && f64::from(s.stale_after_ms) < 2.0 * period_ms {
        return Err(ConfigError::Invalid {
            field: "sensors.stale_after_ms".into(),
            value: s.stale_after_ms.to_string(),
            allowed: format!(
                "at least two conversion periods of the tension sensor ({:.0} ms for the {} of sensors.sample_rate_sps)",
                (2.0 * period_ms).ceil(),
                converter_name(config)
            ),
        });
    }
    let delay = loop_delay(config);
    let g = plant_gain(config);
    let (kp, ki) = (c.tension_kp_nm_per_n, c.tension_ki_nm_per_n_s);
    let configured = pi_margins(g, kp, ki, delay);
    if configured.acceptable() {
        return Ok(TensionLoopPlan::Full(configured));
    }
    let margins = |m: &LoopMargins| {
        format!(
            "phase margin {:.0}° (at least {MIN_PHASE_MARGIN_DEG:.0}°), gain margin {:.2} (at least {MIN_GAIN_MARGIN})",
            m.phase_margin_deg, m.gain_margin
        )
    };
    let Some(scale) = stable_gain_scale(g, kp, ki, delay) else {
        return Err(ConfigError::Invalid {
            field: "sensors.sample_rate_sps".into(),
            value: s.sample_rate_sps.to_string(),
            allowed: format!(
                "fast enough for a tension loop: the {} hands the tension back {:.0} ms late, and no useful fraction of control.tension_kp_nm_per_n = {kp} and control.tension_ki_nm_per_n_s = {ki} is stable ({})",
                converter_name(config),
                1e3 * delay,
                margins(&configured)
            ),
        });
    };
    let reduced = pi_margins(g, scale * kp, scale * ki, delay);
    if !c.allow_degraded_tension_loop {
        return Err(ConfigError::Invalid {
            field: "control.tension_ki_nm_per_n_s".into(),
            value: ki.to_string(),
            allowed: format!(
                "stable on the tension sensor: the {} (sensors.sample_rate_sps) hands the tension back {:.1} ms late, and with control.tension_kp_nm_per_n = {kp} the loop has {}; lower both gains to {:.3} of theirs, use a faster converter, or set control.allow_degraded_tension_loop = true to run with the lower gains",
                converter_name(config),
                1e3 * delay,
                margins(&configured),
                scale
            ),
        });
    }
    Ok(TensionLoopPlan::Degraded {
        scale,
        configured,
        reduced,
    })
}

/// A one-line account of the sensor's timing and the loop, for `videt config check` and the
/// service's start-up log.
pub fn describe(config: &Config) -> String {
    let m = converter_model(config);
    let timing = format!(
        "tension sensor: {}: a new sample every {:.2} ms, filter delay {:.2} ms, loop delay {:.2} ms",
        converter_name(config),
        1e3 * m.period_s(),
        1e3 * m.group_delay_s(),
        1e3 * loop_delay(config)
    );
    match plan(config) {
        Ok(TensionLoopPlan::Full(g)) => format!(
            "{timing}; PI tension loop at the configured gains: phase margin {:.0}°, gain margin {:.2}",
            g.phase_margin_deg, g.gain_margin
        ),
        Ok(TensionLoopPlan::Degraded { scale, reduced, .. }) => format!(
            "{timing}; PI tension loop DEGRADED to {scale:.3} of the configured gains: phase margin {:.0}°, gain margin {:.2}",
            reduced.phase_margin_deg, reduced.gain_margin
        ),
        Err(e) => format!("{timing}; {e}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hx711(rate: u32) -> Config {
        let mut c = Config::default();
        c.sensors.adc = TensionAdc::Hx711;
        c.sensors.sample_rate_sps = rate;
        c.sensors.stale_after_ms = 250;
        c
    }

    #[test]
    fn the_default_ads1220_runs_the_configured_gains() {
        let c = Config::default();
        assert!(matches!(plan(&c), Ok(TensionLoopPlan::Full(_))));
        assert!(describe(&c).contains("ADS1220 at 2000 samples/s (turbo mode)"));
        assert!((loop_delay(&c) - 2.0e-3).abs() < 1e-12);
    }

    #[test]
    fn an_80_sps_hx711_is_refused_unless_the_degraded_mode_is_asked_for() {
        let mut c = hx711(80);
        let e = plan(&c).unwrap_err().to_string();
        for needle in [
            "control.tension_ki_nm_per_n_s = 0.04",
            "HX711 at 80 samples/s",
            "control.allow_degraded_tension_loop = true",
        ] {
            assert!(e.contains(needle), "{needle:?} missing from {e}");
        }
        c.control.allow_degraded_tension_loop = true;
        let p = plan(&c).unwrap();
        assert!(p.gain_scale() < 1.0 && p.gain_scale() > 0.01, "{p:?}");
        assert!(describe(&c).contains("DEGRADED"));
    }

    #[test]
    fn a_staleness_limit_shorter_than_two_conversions_is_refused() {
        let mut c = hx711(10);
        c.sensors.stale_after_ms = 20;
        let e = plan(&c).unwrap_err().to_string();
        assert!(
            e.contains("sensors.stale_after_ms = 20") && e.contains("200 ms"),
            "{e}"
        );
    }

    #[test]
    fn the_drive_inputs_are_read_every_period() {
        let mut c = Config::default();
        c.sensors.adc = TensionAdc::Drive;
        let m = converter_model(&c);
        assert_eq!((m.sample_rate_sps, m.filter_order), (1000.0, 0));
        assert!(matches!(plan(&c), Ok(TensionLoopPlan::Full(_))));
    }
}
