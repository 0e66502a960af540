//! The status the control thread publishes for the supervisor: a lock-free, wait-free triple
//! buffer of a plain `Copy` snapshot, written every period.

use videt_control::safety::SafetyState;

use crate::control_loop::{CycleObserver, WindowStats};
use crate::cycle::CycleRecord;

/// The latest period and the last one-second window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StatusSnapshot {
    /// The latest period.
    pub record: CycleRecord,
    /// The last complete one-second window.
    pub window: WindowStats,
    /// The fraction of the configured PI gains the tension loop runs with when it is degraded
    /// (a sensor too slow for them); `None` at the configured gains.
    pub tension_loop_degraded: Option<f64>,
    /// Wires of the device (the record's first `wires` per-wire slots are its).
    pub wires: usize,
    /// The device's configuration name (`wireman3`, `planar2`, `polar1`).
    pub device: &'static str,
}

impl StatusSnapshot {
    /// The device's measured tensions, one per wire, newtons.
    pub fn tensions_n(&self) -> &[f64] {
        &self.record.tension_measured_n[..self.wires.clamp(1, self.record.tension_measured_n.len())]
    }

    /// One human-readable status line.
    pub fn line(&self) -> String {
        let r = &self.record;
        let p = r.position_m;
        let t: Vec<String> = self
            .tensions_n()
            .iter()
            .map(|t| format!("{t:5.2}"))
            .collect();
        let contact_n = if r.in_contact {
            (r.rendered_force_n[0].powi(2)
                + r.rendered_force_n[1].powi(2)
                + r.rendered_force_n[2].powi(2))
            .sqrt()
        } else {
            0.0
        };
        let state = match r.safety {
            SafetyState::Normal => "normal".to_string(),
            SafetyState::MinimumTension(reason) => format!("min-tension ({})", reason.as_str()),
            SafetyState::PowerOff(reason) => format!("power-off ({})", reason.as_str()),
        };
        // Until the first one-second window closes there is no rate to show.
        let timing = if self.window.rate_hz > 0.0 {
            format!(
                "rate {:7.1} Hz  worst cycle {:6.1} µs (wake-up {:6.1} µs)",
                self.window.rate_hz,
                self.window.worst_compute_ns as f64 * 1e-3,
                self.window.worst_latency_ns as f64 * 1e-3,
            )
        } else {
            "rate (first one-second window still open)".to_string()
        };
        let degraded = match self.tension_loop_degraded {
            Some(scale) => format!("  tension loop degraded (PI gains x{scale:.3})"),
            None => String::new(),
        };
        format!(
            "t={:7.2}s {timing}  x=({:+.4}, {:+.4}, {:+.4}) m  T=({}) N  contact {:5.2} N  {}{degraded}",
            r.time.as_secs_f64(),
            p[0],
            p[1],
            p[2],
            t.join(", "),
            contact_n,
            state
        )
    }
}

/// Publishes every period into a triple buffer (wait-free, no allocation).
pub struct StatusPublisher {
    input: triple_buffer::Input<StatusSnapshot>,
    tension_loop_degraded: Option<f64>,
    wires: usize,
    device: &'static str,
}

impl StatusPublisher {
    /// Say which device the records come from (default: the WireMan).
    pub fn set_device(&mut self, device: &'static str, wires: usize) {
        self.device = device;
        self.wires = wires;
    }

    /// Say in every snapshot that the tension loop runs at `scale` of its configured gains.
    pub fn set_tension_loop_degraded(&mut self, scale: Option<f64>) {
        self.tension_loop_degraded = scale;
    }
}

/// Reads the latest published status.
pub struct StatusReader {
    output: triple_buffer::Output<StatusSnapshot>,
}

/// A connected publisher/reader pair.
pub fn status_channel() -> (StatusPublisher, StatusReader) {
    let (input, output) = triple_buffer::triple_buffer(&StatusSnapshot::default());
    (
        StatusPublisher {
            input,
            tension_loop_degraded: None,
            wires: 3,
            device: "wireman3",
        },
        StatusReader { output },
    )
}

impl CycleObserver for StatusPublisher {
    fn observe(&mut self, record: &CycleRecord, window: &WindowStats) {
        self.input.write(StatusSnapshot {
            record: *record,
            window: *window,
            tension_loop_degraded: self.tension_loop_degraded,
            wires: self.wires,
            device: self.device,
        });
    }
}

impl StatusReader {
    /// The latest snapshot.
    pub fn latest(&mut self) -> StatusSnapshot {
        *self.output.read()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_before_the_first_window_says_so_instead_of_a_zero_rate() {
        let pending = StatusSnapshot::default().line();
        assert!(
            pending.contains("first one-second window still open"),
            "{pending}"
        );
        assert!(!pending.contains("0.0 Hz"), "{pending}");
        let mut s = StatusSnapshot::default();
        s.window.rate_hz = 999.5;
        s.window.worst_compute_ns = 42_800;
        let line = s.line();
        assert!(
            line.contains("rate   999.5 Hz  worst cycle   42.8 µs"),
            "{line}"
        );
    }

    #[test]
    fn a_degraded_tension_loop_is_in_every_snapshot_and_line() {
        let (mut publisher, mut reader) = status_channel();
        publisher.observe(&CycleRecord::default(), &WindowStats::default());
        assert_eq!(reader.latest().tension_loop_degraded, None);
        assert!(!reader.latest().line().contains("degraded"));
        publisher.set_tension_loop_degraded(Some(0.656));
        publisher.observe(&CycleRecord::default(), &WindowStats::default());
        let s = reader.latest();
        assert_eq!(s.tension_loop_degraded, Some(0.656));
        assert!(
            s.line()
                .ends_with("tension loop degraded (PI gains x0.656)"),
            "{}",
            s.line()
        );
    }
}
