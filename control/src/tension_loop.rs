//! Whether the PI tension loop is stable on a given tension sensor, and how far its gains must
//! come down when it is not.
//!
//! The loop around one wire: the PI turns the tension error into motor torque, the wire turns
//! torque into tension (statically: `1 / feed-forward` newtons per newton-metre), and the
//! sensor hands the tension back late. The lateness is a pure delay: the converter's filter
//! (its group delay), the hold between conversions (half a conversion period on average) and
//! one control period (measure, compute, command). With `G` the plant gain and `τ` the delay,
//! the open loop is `L(jω) = G·(kp + ki/(jω))·e^{−jωτ}`; its phase margin at the gain
//! crossover and its gain margin at the phase crossover say how close the loop is to
//! oscillating. The static plant is the conservative case (a real wire and motor roll the gain
//! off at high frequency); the twin checks the verdict with the plant's dynamics.

use core::f64::consts::PI;

use nalgebra::ComplexField;

/// Smallest phase margin accepted, degrees.
pub const MIN_PHASE_MARGIN_DEG: f64 = 45.0;
/// Smallest gain margin accepted (3.5 dB).
pub const MIN_GAIN_MARGIN: f64 = 1.5;
/// Below this fraction of the configured gains the loop no longer corrects anything worth
/// having: a sensor that needs less is refused even in the degraded mode.
pub const MIN_GAIN_SCALE: f64 = 0.01;

/// The loop's margins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopMargins {
    /// Phase margin, degrees (at the gain crossover; 180 without one).
    pub phase_margin_deg: f64,
    /// Gain margin, as a factor (at the phase crossover; infinite without one).
    pub gain_margin: f64,
    /// Gain crossover frequency, rad/s (0 without one).
    pub crossover_rad_s: f64,
}

impl LoopMargins {
    /// Both margins at least the accepted minimums.
    pub fn acceptable(&self) -> bool {
        self.phase_margin_deg >= MIN_PHASE_MARGIN_DEG && self.gain_margin >= MIN_GAIN_MARGIN
    }
}

/// The total delay of the tension measurement in the loop, seconds: the sensor's group delay,
/// half its sample period (the hold) and one control period.
pub fn loop_delay_s(group_delay_s: f64, sample_period_s: f64, control_period_s: f64) -> f64 {
    group_delay_s + 0.5 * sample_period_s + control_period_s
}

/// Margins of the PI loop with plant gain `plant_n_per_nm` (newtons of tension per newton-metre
/// of torque), gains `kp` (N·m/N) and `ki` (N·m/(N·s)), and delay `delay_s`. Evaluated on a
/// logarithmic grid from 0.01 to 10⁶ rad/s (bounded: 4000 points).
pub fn pi_margins(plant_n_per_nm: f64, kp: f64, ki: f64, delay_s: f64) -> LoopMargins {
    let magnitude = |w: f64| plant_n_per_nm * ComplexField::sqrt(kp * kp + (ki / w) * (ki / w));
    // The phase lag, positive: the PI's plus the delay's.
    let lag = |w: f64| ComplexField::atan(ki / (kp * w)) + w * delay_s;
    const POINTS: usize = 4000;
    let (lo, hi) = (ComplexField::ln(1e-2f64), ComplexField::ln(1e6f64));
    let at = |k: usize| ComplexField::exp(lo + (hi - lo) * k as f64 / (POINTS - 1) as f64);
    let mut margins = LoopMargins {
        phase_margin_deg: 180.0,
        gain_margin: f64::INFINITY,
        crossover_rad_s: 0.0,
    };
    let mut crossover_found = false;
    let mut phase_found = false;
    for k in 1..POINTS {
        let (w0, w1) = (at(k - 1), at(k));
        if !crossover_found && magnitude(w0) >= 1.0 && magnitude(w1) < 1.0 {
            let w = bisect(w0, w1, |w| magnitude(w) - 1.0);
            margins.crossover_rad_s = w;
            margins.phase_margin_deg = (PI - lag(w)).to_degrees();
            crossover_found = true;
        }
        if !phase_found && lag(w0) <= PI && lag(w1) > PI {
            let w = bisect(w0, w1, |w| lag(w) - PI);
            margins.gain_margin = 1.0 / magnitude(w);
            phase_found = true;
        }
        if crossover_found && phase_found {
            break;
        }
    }
    margins
}

/// A root of `f` in `[a, b]` where `f` changes sign (60 halvings).
fn bisect(mut a: f64, mut b: f64, f: impl Fn(f64) -> f64) -> f64 {
    let fa = f(a);
    for _ in 0..60 {
        let m = 0.5 * (a + b);
        if (f(m) > 0.0) == (fa > 0.0) {
            a = m;
        } else {
            b = m;
        }
    }
    0.5 * (a + b)
}

/// The largest fraction (at most 1) of both PI gains at which the loop keeps the accepted
/// margins; `None` when even [`MIN_GAIN_SCALE`] does not.
pub fn stable_gain_scale(plant_n_per_nm: f64, kp: f64, ki: f64, delay_s: f64) -> Option<f64> {
    let ok = |s: f64| pi_margins(plant_n_per_nm, s * kp, s * ki, delay_s).acceptable();
    if ok(1.0) {
        return Some(1.0);
    }
    if !ok(MIN_GAIN_SCALE) {
        return None;
    }
    let (mut good, mut bad) = (MIN_GAIN_SCALE, 1.0);
    for _ in 0..40 {
        let m = ComplexField::sqrt(good * bad);
        if ok(m) {
            good = m;
        } else {
            bad = m;
        }
    }
    Some(good)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_integrator_with_delay_has_the_textbook_margins() {
        // kp -> 0: L = G·ki/(jω)·e^{-jωτ}: crossover at G·ki, phase margin 90° - G·ki·τ,
        // phase crossover at π/(2τ) with gain margin π/(2·G·ki·τ).
        let (g, ki, tau) = (1250.0, 0.04, 0.004);
        let m = pi_margins(g, 1e-12, ki, tau);
        let wc = g * ki;
        assert!((m.crossover_rad_s - wc).abs() < 1e-6 * wc, "{m:?}");
        let pm = 90.0 - (wc * tau).to_degrees();
        assert!((m.phase_margin_deg - pm).abs() < 1e-3, "{m:?} vs {pm}");
        let gm = PI / (2.0 * wc * tau);
        assert!((m.gain_margin - gm).abs() < 1e-3 * gm, "{m:?} vs {gm}");
    }

    #[test]
    fn the_default_loop_is_comfortable_on_a_fast_converter_and_not_on_a_slow_one() {
        // The paper's transmission (8e-4 N·m/N), kp 4e-4, ki 4e-2, 1 kHz control.
        let g = 1.0 / 8e-4;
        let ads1220_turbo = loop_delay_s(1.5 / 2000.0, 1.0 / 2000.0, 1e-3);
        assert!(pi_margins(g, 4e-4, 4e-2, ads1220_turbo).acceptable());
        let hx711_80 = loop_delay_s(2.0 / 80.0, 1.0 / 80.0, 1e-3);
        let m = pi_margins(g, 4e-4, 4e-2, hx711_80);
        assert!(!m.acceptable(), "{m:?}");
        let s = stable_gain_scale(g, 4e-4, 4e-2, hx711_80).unwrap();
        assert!(s < 1.0 && s > MIN_GAIN_SCALE, "{s}");
        assert!(pi_margins(g, s * 4e-4, s * 4e-2, hx711_80).acceptable());
        assert!(!pi_margins(g, 1.2 * s * 4e-4, 1.2 * s * 4e-2, hx711_80).acceptable());
        assert_eq!(stable_gain_scale(g, 4e-4, 4e-2, ads1220_turbo), Some(1.0));
    }

    #[test]
    fn a_loop_too_slow_for_any_useful_gain_is_refused() {
        assert_eq!(stable_gain_scale(1250.0, 4e-4, 4e-2, 10.0), None);
    }
}
