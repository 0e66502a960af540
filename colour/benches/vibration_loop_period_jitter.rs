//! Measures the vibration loop on the host clock: carrier frequency and duty per level as
//! recorded by the twin's recording vibrotactors (stamped with the same clock), and the loop's
//! own period jitter (min / max / p99 of |period - nominal|, missed ticks).
//!
//! `cargo bench -p videt-colour --bench vibration_loop_period_jitter [-- SECONDS]` (default 3 s).
//! The figures depend on the machine's load and scheduling policy: the bench asks for
//! SCHED_FIFO 70 (as `videtd`'s colour thread does) and says whether it got it.

use std::sync::Arc;

use videt_colour::level::Level::{High, Low, Mid};
use videt_colour::{
    HostClock, Pattern, PatternConfig, RecordingVibrotactors, VibrationInputs, VibrationLoop,
};
use videt_hal::Clock;

/// Ask for SCHED_FIFO at `priority` for the calling thread.
fn set_fifo(priority: i32) -> Result<(), std::io::Error> {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: `param` is a valid sched_param; 0 means the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

fn main() {
    let scheduling = match set_fifo(70) {
        Ok(()) => "SCHED_FIFO 70".to_string(),
        Err(e) => format!("SCHED_OTHER (SCHED_FIFO refused: {e})"),
    };
    let seconds: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(3.0);
    let clock = HostClock::new();
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([Low, Mid, High]));
    let pattern = Pattern::new(PatternConfig::default()).expect("default pattern");
    let vibro = RecordingVibrotactors::new(clock, 1_000_000);
    let ticks_per_period = 20;
    let mut lp =
        VibrationLoop::new(vibro, clock, pattern, ticks_per_period, inputs).expect("default loop");
    let periods = (seconds * 75.0).round() as u64;
    let start = clock.now();
    lp.run_ticks(periods * u64::from(ticks_per_period))
        .expect("recording vibrotactors do not fail");
    let end = clock.now();
    // Whole carrier periods from the first tick.
    let window_end = start.add_nanos(
        (end.nanos_since(start) / pattern.period_ns()).saturating_sub(1) * pattern.period_ns(),
    );
    println!(
        "vibration loop on the host clock, {scheduling}: {:.2} s, {} ticks of nominal {} ns ({:.0} Hz)",
        end.nanos_since(start) as f64 * 1e-9,
        periods * u64::from(ticks_per_period),
        lp.tick_period_ns(),
        1e9 / lp.tick_period_ns() as f64
    );
    for (channel, name, level) in [(0, "red", Low), (1, "green", Mid), (2, "blue", High)] {
        let s = lp
            .vibrotactors()
            .channel_summary(channel, start, window_end);
        println!(
            "  {name:5} level {:4}: frequency {} Hz, duty {:.2} % (nominal {:.0} %), period range {}",
            level.as_str(),
            s.frequency_hz
                .map_or("-".to_string(), |f| format!("{f:.3}")),
            100.0 * s.duty,
            100.0 * PatternConfig::default().duty[level as usize],
            s.period_range_ns.map_or("-".to_string(), |(lo, hi)| format!(
                "{:.3}..{:.3} ms",
                lo as f64 * 1e-6,
                hi as f64 * 1e-6
            )),
        );
    }
    let j = lp.jitter();
    println!(
        "  loop period: min {} ns, max {} ns, mean {:.0} ns; |period - nominal| p50 {}, p99 {}; max lateness {} ns; missed ticks {}; dropped edges {}",
        j.min_period_ns().unwrap_or(0),
        j.max_period_ns().unwrap_or(0),
        j.mean_period_ns().unwrap_or(0.0),
        j.deviation_quantile_ns(0.5).map_or("> 2 ms".into(), |v| format!("<= {v} ns")),
        j.p99_deviation_ns().map_or("> 2 ms".into(), |v| format!("<= {v} ns")),
        j.max_lateness_ns(),
        j.missed_ticks(),
        lp.vibrotactors().dropped_edges()
    );
}
