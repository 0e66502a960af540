//! What a session's figures draw, gathered as the log is read in memory that does not grow
//! with the session's length.
//!
//! A figure is at most about a thousand pixels wide, so a line over an hour of periods draws
//! the same picture as a line through, for each narrow slice of time, the period that opens
//! the slice, the one that closes it and those that hold each plotted quantity's lowest and
//! highest value (the slice's first, last, minimum and maximum: the line's envelope in every
//! pixel column is kept). [`Decimator`] keeps those periods; the slices start one period wide
//! and double in width whenever there are more than twice [`SLICES`] of them, so a short
//! session keeps every period and a long one at most `2 × SLICES` slices.

use videt_control::safety::SafetyState;
use videt_runtime::cycle::CycleRecord;
use videt_runtime::histogram::Histogram;

/// The narrowest slicing a figure is drawn from: more slices than the widest figure has pixel
/// columns.
pub const SLICES: usize = 1024;
/// First contacts and safety transitions kept for the figures; beyond them a long session's
/// figure names how many more there were.
pub const MARKS: usize = 20_000;

/// One slice of time: the items that open and close it and those that hold each quantity's
/// lowest and highest value in it.
#[derive(Debug, Clone)]
struct Slice<T, const K: usize> {
    /// The slice's number at the current width.
    number: u64,
    /// Items that hold a place, with their sequence numbers (no two equal).
    kept: Vec<(u64, T)>,
    first: u64,
    last: (u64, T),
    low: [Option<(f64, u64)>; K],
    high: [Option<(f64, u64)>; K],
}

impl<T: Clone, const K: usize> Slice<T, K> {
    fn holds(&self, seq: u64) -> bool {
        seq == self.first
            || self
                .low
                .iter()
                .chain(&self.high)
                .any(|p| p.is_some_and(|(_, s)| s == seq))
    }

    /// A later item of the slice.
    fn offer(&mut self, seq: u64, item: T, values: [Option<f64>; K]) {
        let mut wins = false;
        for (k, v) in values.iter().enumerate() {
            let Some(v) = *v else {
                continue;
            };
            if self.low[k].is_none_or(|(lo, _)| v < lo) {
                self.low[k] = Some((v, seq));
                wins = true;
            }
            if self.high[k].is_none_or(|(hi, _)| v > hi) {
                self.high[k] = Some((v, seq));
                wins = true;
            }
        }
        if wins {
            self.kept.push((seq, item.clone()));
            // At most 2K + 1 items hold a place (the first and an extreme per side and
            // quantity): compacting past 2K + 2 keeps the slice near that bound.
            if self.kept.len() > 2 * K + 2 {
                self.compact();
            }
        }
        self.last = (seq, item);
    }

    /// Drop the kept items that no longer hold a place.
    fn compact(&mut self) {
        let mut kept = std::mem::take(&mut self.kept);
        kept.retain(|(seq, _)| self.holds(*seq));
        self.kept = kept;
    }

    /// This slice followed by `later`, as one.
    fn merge(mut self, later: Slice<T, K>) -> Slice<T, K> {
        for k in 0..K {
            self.low[k] = pick(self.low[k], later.low[k], |a, b| b < a);
            self.high[k] = pick(self.high[k], later.high[k], |a, b| b > a);
        }
        // The earlier slice's last item is not kept unless it holds a place; the later's
        // first becomes an ordinary item.
        let (last_seq, last_item) = self.last.clone();
        self.kept.push((last_seq, last_item));
        self.kept.extend(later.kept);
        self.last = later.last;
        self.kept.sort_by_key(|(seq, _)| *seq);
        self.kept.dedup_by_key(|(seq, _)| *seq);
        self.compact();
        self
    }

    /// The items of the slice, in order, each once.
    fn items(&self) -> impl Iterator<Item = &T> {
        let last = (self.last.0, &self.last.1);
        let tail = (!self.kept.iter().any(|(s, _)| *s == last.0)).then_some(last);
        self.kept
            .iter()
            .map(|(s, t)| (*s, t))
            .chain(tail)
            .map(|(_, t)| t)
    }
}

fn pick(
    a: Option<(f64, u64)>,
    b: Option<(f64, u64)>,
    better: fn(f64, f64) -> bool,
) -> Option<(f64, u64)> {
    match (a, b) {
        (Some(x), Some(y)) if better(x.0, y.0) => Some(y),
        (Some(x), _) => Some(x),
        (None, y) => y,
    }
}

/// Keeps, of items arriving in time order, those a line figure of `K` quantities needs (see
/// the module's documentation); its memory is bounded by `2 × SLICES` slices whatever the
/// number of items.
#[derive(Debug, Clone)]
pub struct Decimator<T, const K: usize> {
    t0: Option<f64>,
    width_s: f64,
    slices: Vec<Slice<T, K>>,
    next_seq: u64,
}

impl<T: Clone, const K: usize> Default for Decimator<T, K> {
    fn default() -> Self {
        Decimator::new()
    }
}

impl<T: Clone, const K: usize> Decimator<T, K> {
    /// Nothing kept yet; the first slices are narrower than a period at 10 kHz.
    pub fn new() -> Decimator<T, K> {
        Decimator {
            t0: None,
            width_s: 1e-4,
            slices: Vec::new(),
            next_seq: 0,
        }
    }

    /// Offer `item`, at `t_s` seconds, whose quantities are `values` (`None`: not drawn for
    /// this item).
    pub fn add(&mut self, t_s: f64, item: T, values: [Option<f64>; K]) {
        let t0 = *self.t0.get_or_insert(t_s);
        let seq = self.next_seq;
        self.next_seq += 1;
        let values = values.map(|v| v.filter(|v| v.is_finite()));
        let number_at = |width_s: f64| ((t_s - t0) / width_s).max(0.0) as u64;
        let opens_a_slice = |slices: &[Slice<T, K>], width_s: f64| {
            slices.last().is_none_or(|s| number_at(width_s) > s.number)
        };
        while opens_a_slice(&self.slices, self.width_s) && self.slices.len() >= 2 * SLICES {
            self.widen();
        }
        let number = number_at(self.width_s);
        match self.slices.last_mut() {
            // Time runs forwards; an item stamped earlier than the last joins the last slice.
            Some(slice) if number <= slice.number => slice.offer(seq, item, values),
            _ => self.slices.push(Slice {
                number,
                kept: vec![(seq, item.clone())],
                first: seq,
                last: (seq, item),
                low: values.map(|v| v.map(|v| (v, seq))),
                high: values.map(|v| v.map(|v| (v, seq))),
            }),
        }
    }

    /// Double the slices' width: neighbours merge.
    fn widen(&mut self) {
        self.width_s *= 2.0;
        let mut merged: Vec<Slice<T, K>> = Vec::with_capacity(self.slices.len() / 2 + 1);
        for mut slice in std::mem::take(&mut self.slices) {
            slice.number /= 2;
            match merged.last_mut() {
                Some(m) if m.number == slice.number => {
                    let earlier = merged.pop().expect("a slice");
                    merged.push(earlier.merge(slice));
                }
                _ => {
                    slice.compact();
                    merged.push(slice);
                }
            }
        }
        self.slices = merged;
    }

    /// Items offered.
    pub fn offered(&self) -> u64 {
        self.next_seq
    }

    /// The kept items, in the order they came.
    pub fn kept(&self) -> Vec<T> {
        self.slices
            .iter()
            .flat_map(|s| s.items())
            .cloned()
            .collect()
    }
}

/// What the figures draw of a period (a small part of its record).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DrawnPeriod {
    /// The period's time on the service's clock, s.
    pub time_s: f64,
    /// The thimble's position, m.
    pub position_m: [f64; 3],
    /// Measured tension per wire, N.
    pub tension_measured_n: [f64; 3],
    /// Tension set-point per wire, N.
    pub tension_setpoint_n: [f64; 3],
    /// The desired force f_e, N.
    pub desired_force_n: [f64; 3],
    /// The force the set-points render, N.
    pub rendered_force_n: [f64; 3],
    /// Whether the thimble touched the surface.
    pub in_contact: bool,
}

/// The length of a vector.
pub fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

impl DrawnPeriod {
    /// The index V (eq. 8) in contact, where a force was asked (`None` elsewhere).
    pub fn contact_v(&self) -> Option<f64> {
        (self.in_contact && norm(self.desired_force_n) > 0.05).then(|| {
            videt_control::measures::v_index(
                &nalgebra::Vector3::from(self.rendered_force_n),
                &nalgebra::Vector3::from(self.desired_force_n),
            )
        })
    }

    /// What the figures draw of `r`.
    pub fn of(r: &CycleRecord) -> DrawnPeriod {
        DrawnPeriod {
            time_s: r.time.as_secs_f64(),
            position_m: r.position_m,
            tension_measured_n: r.tension_measured_n,
            tension_setpoint_n: r.tension_setpoint_n,
            desired_force_n: r.desired_force_n,
            rendered_force_n: r.rendered_force_n,
            in_contact: r.in_contact,
        }
    }
}

/// The quantities of a period the session's figures draw: per wire the measured tension and
/// the set-point, |f_e| and |f|, the thimble's x and z, and the index V in contact.
fn drawn_quantities(p: &DrawnPeriod) -> [Option<f64>; 11] {
    let [m0, m1, m2] = p.tension_measured_n.map(Some);
    let [s0, s1, s2] = p.tension_setpoint_n.map(Some);
    [
        m0,
        m1,
        m2,
        s0,
        s1,
        s2,
        Some(norm(p.desired_force_n)),
        Some(norm(p.rendered_force_n)),
        Some(p.position_m[0]),
        Some(p.position_m[2]),
        p.contact_v(),
    ]
}

/// Marks kept up to a bound, with a count of those beyond it.
#[derive(Debug, Clone, Default)]
pub struct Marks<T> {
    /// The first [`MARKS`].
    pub kept: Vec<T>,
    /// How many more there were.
    pub beyond: u64,
}

impl<T> Marks<T> {
    /// Keep `mark`, or count it when the bound is reached.
    pub fn push(&mut self, mark: T) {
        if self.kept.len() < MARKS {
            self.kept.push(mark);
        } else {
            self.beyond += 1;
        }
    }
}

/// The safety state over a session, as its periods come: the transitions, kept up to a bound.
#[derive(Debug, Clone, Default)]
pub struct SafetyTimeline {
    /// The first period's time, s (`None`: no period yet).
    pub t0_s: Option<f64>,
    /// The last period's time, s.
    pub t_end_s: f64,
    /// Transitions: time from the first period (s) and the new state. The state before the
    /// first period counts as `Normal`.
    pub transitions: Marks<(f64, SafetyState)>,
    last: SafetyState,
}

impl SafetyTimeline {
    /// One period, in the log's order.
    pub fn add(&mut self, r: &CycleRecord) {
        let t = r.time.as_secs_f64();
        let t0 = *self.t0_s.get_or_insert(t);
        self.t_end_s = t;
        if r.safety != self.last {
            self.transitions.push((t - t0, r.safety));
            self.last = r.safety;
        }
    }
}

/// What the session's figures draw, gathered period by period.
#[derive(Debug, Clone, Default)]
pub struct SessionFigureData {
    periods: Decimator<DrawnPeriod, 11>,
    /// The safety state over the session (and its first and last period's times).
    pub safety: SafetyTimeline,
    /// Where the finger met the surface (a period in contact after one out of it): x and z, m.
    pub first_contacts: Marks<(f64, f64)>,
    /// Wake-up latency of every period.
    pub wake: Histogram,
    /// Compute time of every period.
    pub compute: Histogram,
    last_in_contact: bool,
    /// The surface version rendered longest and for how many periods, and the current run.
    longest_surface: Option<(u64, u64)>,
    run: Option<(u64, u64)>,
}

impl SessionFigureData {
    /// One period, in the log's order.
    pub fn add(&mut self, r: &CycleRecord) {
        self.safety.add(r);
        if r.in_contact && !self.last_in_contact && self.periods.offered() > 0 {
            self.first_contacts.push((r.position_m[0], r.position_m[2]));
        }
        self.last_in_contact = r.in_contact;
        self.wake.record(r.wake_latency_ns);
        self.compute.record(r.compute_ns);
        // A surface version is rendered by consecutive periods: the longest run is the
        // version most periods rendered.
        let run = match self.run {
            Some((v, n)) if v == r.surface_version => (v, n + 1),
            _ => (r.surface_version, 1),
        };
        self.run = Some(run);
        if self.longest_surface.is_none_or(|(_, n)| run.1 > n) {
            self.longest_surface = Some(run);
        }
        let drawn = DrawnPeriod::of(r);
        self.periods
            .add(drawn.time_s, drawn, drawn_quantities(&drawn));
    }

    /// Periods offered.
    pub fn periods(&self) -> u64 {
        self.periods.offered()
    }

    /// The periods a figure draws, in order (every period of a short session).
    pub fn drawn_periods(&self) -> Vec<DrawnPeriod> {
        self.periods.kept()
    }

    /// The surface version rendered by the most consecutive periods.
    pub fn session_surface_version(&self) -> Option<u64> {
        self.longest_surface.map(|(v, _)| v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wave(i: u64) -> f64 {
        ((i as f64) * 0.37).sin() * (1.0 + (i % 97) as f64)
    }

    #[test]
    fn a_short_series_is_kept_whole() {
        let mut d = Decimator::<u64, 1>::new();
        for i in 0..1500 {
            d.add(i as f64 * 1e-3, i, [Some(wave(i))]);
        }
        assert_eq!(d.kept(), (0..1500).collect::<Vec<_>>());
    }

    #[test]
    fn a_long_series_keeps_every_slice_envelope_in_bounded_memory() {
        let mut d = Decimator::<u64, 2>::new();
        let n = 2_000_000u64;
        for i in 0..n {
            d.add(i as f64 * 1e-3, i, [Some(wave(i)), Some(-wave(i + 5))]);
        }
        let kept = d.kept();
        assert!(kept.len() <= 2 * SLICES * 6, "{} kept", kept.len());
        assert!(kept.windows(2).all(|w| w[0] < w[1]), "in order, each once");
        assert_eq!(kept.first(), Some(&0));
        assert_eq!(kept.last(), Some(&(n - 1)));
        // Every slice's extremes survive: within each slice of the final width, the kept
        // items reach its lowest and highest value, and its first and last item are kept.
        let width = d.width_s;
        let slice_of = |i: u64| ((i as f64 * 1e-3) / width) as u64;
        let last_slice = slice_of(n - 1);
        for s in [0u64, 17, 400, last_slice] {
            let members: Vec<u64> = (0..n).filter(|&i| slice_of(i) == s).collect();
            let max = members.iter().map(|&i| wave(i)).fold(f64::MIN, f64::max);
            let min = members.iter().map(|&i| wave(i)).fold(f64::MAX, f64::min);
            let in_slice: Vec<u64> = kept.iter().copied().filter(|&i| slice_of(i) == s).collect();
            let kmax = in_slice.iter().map(|&i| wave(i)).fold(f64::MIN, f64::max);
            let kmin = in_slice.iter().map(|&i| wave(i)).fold(f64::MAX, f64::min);
            assert_eq!((kmin, kmax), (min, max), "slice {s}");
            assert!(in_slice.contains(&members[0]), "slice {s}");
            assert!(in_slice.contains(&members[members.len() - 1]), "slice {s}");
        }
    }

    #[test]
    fn the_figure_data_counts_every_period_and_marks_transitions() {
        let mut data = SessionFigureData::default();
        for i in 0..10_000u64 {
            let mut r = CycleRecord {
                cycle: i,
                time: videt_hal::clock::MonoTime(1_000_000 * i),
                wake_latency_ns: 1000 + i % 50,
                surface_version: if i < 3000 {
                    0
                } else if i < 9000 {
                    1
                } else {
                    2
                },
                in_contact: (i / 500) % 2 == 1,
                ..CycleRecord::default()
            };
            if (4000..4100).contains(&i) {
                r.safety =
                    SafetyState::MinimumTension(videt_control::safety::SafetyReason::EmergencyStop);
            }
            data.add(&r);
        }
        assert_eq!(data.periods(), 10_000);
        assert_eq!(data.wake.count(), 10_000);
        assert_eq!(data.safety.transitions.kept.len(), 2);
        assert_eq!(data.first_contacts.kept.len(), 10);
        assert_eq!(data.session_surface_version(), Some(1));
        assert!(data.drawn_periods().len() < 10_000);
        assert!((data.safety.t_end_s - 9.999).abs() < 1e-9);
    }
}
