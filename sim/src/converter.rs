//! The timing of a strain-gauge converter: conversions at its data rate, each the output of its
//! digital filter, quantized to its counts, and held until the next one.
//!
//! A delta-sigma converter's sinc filter of order `N` averages the input `N` times over one
//! conversion period `T`: its impulse response is the uniform B-spline of order `N` stretched
//! to `N·T`, so a conversion completed at `t` weighs the input over `[t − N·T, t]`, has a group
//! delay of `N·T/2` and settles a step in `N` conversions. The HX711 settles in 4 conversions
//! (400 ms at 10 SPS, 50 ms at 80 SPS: its datasheet); the ADS1220's sinc3 filter in 3. The
//! converter samples the truth it is given at the twin's read instants and integrates between
//! them by linear interpolation.

pub use videt_hal::tension::ConverterModel;

/// Truth samples kept per converter: 0.4 s at 1 kHz (an HX711's span at 10 SPS) and margin.
pub const HISTORY: usize = 1024;
/// Quadrature points per conversion period of the filter's span.
const POINTS_PER_PERIOD: u32 = 16;

/// The uniform B-spline of order `n` (support `[0, n]`, unit area) at `x`.
fn bspline(n: u32, x: f64) -> f64 {
    if n == 0 || x < 0.0 || x >= f64::from(n) {
        return 0.0;
    }
    if n == 1 {
        return 1.0;
    }
    let k = f64::from(n - 1);
    (x * bspline(n - 1, x) + (f64::from(n) - x) * bspline(n - 1, x - 1.0)) / k
}

/// One converter: the truth it has seen, its conversion schedule and its held output.
#[derive(Debug, Clone)]
pub struct ConverterTwin {
    model: ConverterModel,
    history: [(f64, f64); HISTORY],
    len: usize,
    head: usize,
    next_conversion_s: f64,
    held_n: f64,
    fresh: bool,
}

impl ConverterTwin {
    /// A converter whose conversions fall at `phase_s + k·T` (converters free-run: their phase
    /// against the control period is arbitrary).
    pub fn new(model: ConverterModel, phase_s: f64) -> ConverterTwin {
        ConverterTwin {
            model,
            history: [(0.0, 0.0); HISTORY],
            len: 0,
            head: 0,
            next_conversion_s: phase_s.rem_euclid(model.period_s()),
            held_n: 0.0,
            fresh: false,
        }
    }

    /// The model.
    pub fn model(&self) -> &ConverterModel {
        &self.model
    }

    /// The input is `truth_n` at `t_s` (non-decreasing instants). The first observation stands
    /// for the past as well: the converter starts settled.
    pub fn observe(&mut self, t_s: f64, truth_n: f64) {
        if self.len == 0 {
            self.held_n = self.quantize(truth_n);
            while self.next_conversion_s <= t_s {
                self.next_conversion_s += self.model.period_s();
            }
        }
        self.history[self.head] = (t_s, truth_n);
        self.head = (self.head + 1) % HISTORY;
        self.len = (self.len + 1).min(HISTORY);
        while self.next_conversion_s <= t_s {
            self.held_n = self.quantize(self.filtered(self.next_conversion_s));
            self.fresh = true;
            self.next_conversion_s += self.model.period_s();
        }
    }

    /// The latest conversion, newtons, and whether it completed since the previous read.
    pub fn read(&mut self) -> (f64, bool) {
        let fresh = core::mem::take(&mut self.fresh);
        (self.held_n, fresh)
    }

    fn quantize(&self, v: f64) -> f64 {
        let q = self.model.newtons_per_count;
        if q > 0.0 && v.is_finite() {
            (v / q).round() * q
        } else {
            v
        }
    }

    /// The input at `t` by linear interpolation of the history (held beyond its ends).
    fn input_at(&self, t: f64) -> f64 {
        let at = |k: usize| self.history[(self.head + HISTORY - self.len + k) % HISTORY];
        let (first, last) = (at(0), at(self.len - 1));
        if t <= first.0 {
            return first.1;
        }
        if t >= last.0 {
            return last.1;
        }
        // Binary search for the segment holding t.
        let (mut lo, mut hi) = (0, self.len - 1);
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            if at(mid).0 <= t {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let (a, b) = (at(lo), at(hi));
        if b.0 > a.0 {
            a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
        } else {
            b.1
        }
    }

    /// The filter's output for a conversion completed at `t`.
    fn filtered(&self, t: f64) -> f64 {
        let n = self.model.filter_order;
        if n == 0 {
            return self.input_at(t);
        }
        let period = self.model.period_s();
        let points = n * POINTS_PER_PERIOD;
        let step = f64::from(n) / f64::from(points);
        let (mut sum, mut weights) = (0.0, 0.0);
        for k in 0..points {
            // Midpoint rule over the B-spline's support, in conversion periods.
            let x = (f64::from(k) + 0.5) * step;
            let w = bspline(n, x);
            sum += w * self.input_at(t - x * period);
            weights += w;
        }
        sum / weights
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(sps: f64, order: u32) -> ConverterModel {
        ConverterModel {
            sample_rate_sps: sps,
            filter_order: order,
            newtons_per_count: 0.0,
        }
    }

    /// Feed `f(t)` at 1 kHz for `seconds`; every (time, output, fresh) read.
    fn run(c: &mut ConverterTwin, seconds: f64, f: impl Fn(f64) -> f64) -> Vec<(f64, f64, bool)> {
        (0..=(seconds * 1000.0) as usize)
            .map(|k| {
                let t = k as f64 * 1e-3;
                c.observe(t, f(t));
                let (v, fresh) = c.read();
                (t, v, fresh)
            })
            .collect()
    }

    #[test]
    fn the_bspline_has_unit_area_and_its_support() {
        for n in 1..=4 {
            let area: f64 = (0..4000)
                .map(|k| bspline(n, (k as f64 + 0.5) * 1e-3))
                .sum::<f64>()
                * 1e-3;
            assert!((area - 1.0).abs() < 1e-6, "order {n}: {area}");
            assert_eq!(bspline(n, -0.1), 0.0);
            assert_eq!(bspline(n, f64::from(n) + 0.1), 0.0);
        }
    }

    #[test]
    fn conversions_arrive_at_the_data_rate_and_are_held_between() {
        let mut c = ConverterTwin::new(model(80.0, 4), 0.003);
        let reads = run(&mut c, 1.0, |_| 5.0);
        let fresh = reads.iter().filter(|r| r.2).count();
        assert!(
            (79..=81).contains(&fresh),
            "{fresh} conversions in 1 s at 80 SPS"
        );
        assert!(reads.iter().all(|r| (r.1 - 5.0).abs() < 1e-12));
    }

    #[test]
    fn a_step_settles_in_the_filter_order_of_conversions() {
        for (sps, order) in [(80.0, 4), (10.0, 4), (330.0, 3)] {
            let mut c = ConverterTwin::new(model(sps, order), 0.0);
            let reads = run(&mut c, 1.5, |t| if t >= 0.5 { 10.0 } else { 0.0 });
            let period = 1.0 / sps;
            let conversions: Vec<_> = reads.iter().filter(|r| r.2 && r.0 > 0.5).collect();
            // The first conversion after the step holds part of it; full after `order`.
            let settled_at = conversions
                .iter()
                .find(|r| (r.1 - 10.0).abs() < 1e-9)
                .unwrap()
                .0;
            let expected = 0.5 + f64::from(order) * period;
            assert!(
                settled_at >= expected - 2e-3 && settled_at <= expected + period + 2e-3,
                "{sps} SPS sinc{order}: settled at {settled_at}, expected ~{expected}"
            );
            assert!(conversions[0].1 < 10.0 && conversions[0].1 >= 0.0);
        }
    }

    #[test]
    fn a_ramp_is_delayed_by_the_group_delay() {
        let m = model(80.0, 4);
        let mut c = ConverterTwin::new(m, 0.0);
        let reads = run(&mut c, 1.0, |t| 100.0 * t);
        let (t, v, _) = *reads.iter().rev().find(|r| r.2).unwrap();
        // At a conversion instant the output is the ramp group-delay earlier.
        let delay = t - v / 100.0;
        assert!(
            (delay - m.group_delay_s()).abs() < 1e-4,
            "{delay} vs {}",
            m.group_delay_s()
        );
        assert!((m.group_delay_s() - 0.025).abs() < 1e-12);
    }

    #[test]
    fn outputs_are_quantized_to_the_count() {
        let mut c = ConverterTwin::new(
            ConverterModel {
                newtons_per_count: 0.25,
                ..model(1000.0, 3)
            },
            0.0,
        );
        for (_, v, _) in run(&mut c, 0.2, |t| 3.1 + t) {
            assert!(((v / 0.25) - (v / 0.25).round()).abs() < 1e-9, "{v}");
        }
    }

    #[test]
    fn a_converter_faster_than_the_reads_is_fresh_at_every_read() {
        let mut c = ConverterTwin::new(model(2000.0, 3), 0.0);
        let reads = run(&mut c, 0.1, |t| t);
        assert!(reads.iter().skip(1).all(|r| r.2));
    }
}
