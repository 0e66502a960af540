//! The vibration loop on the digital twin: simulated time, recording vibrotactors. Checks the
//! carrier frequency (75 Hz ± 1 %), the duty of each level, quiet safe state and shutdown, the
//! reaction to a failing output, and that a colour wobbling across a threshold within the
//! hysteresis band does not change what the finger feels.

use std::sync::Arc;

use videt_colour::level::Level::{High as H, Low as L, Mid as M};
use videt_colour::twin::summarize;
use videt_colour::{
    Pattern, PatternConfig, Quantizer, QuantizerConfig, RecordingVibrotactors, SimulatedClock,
    VibrationInputs, VibrationLoop,
};
use videt_hal::{Clock, ErrorKind, MonoTime};

const START: MonoTime = MonoTime(5_000_000_000);
const TICKS_PER_PERIOD: u32 = 20;

type TwinLoop = VibrationLoop<RecordingVibrotactors<SimulatedClock>, SimulatedClock>;

fn twin_loop(clock: SimulatedClock, inputs: Arc<VibrationInputs>) -> TwinLoop {
    let vibro = RecordingVibrotactors::new(clock.clone(), 100_000);
    let pattern = Pattern::new(PatternConfig::default()).unwrap();
    VibrationLoop::new(vibro, clock, pattern, TICKS_PER_PERIOD, inputs).unwrap()
}

fn within(value: f64, target: f64, rel: f64) -> bool {
    (value - target).abs() <= rel * target
}

#[test]
fn frequency_and_duty_per_level_on_simulated_time() {
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([L, M, H]));
    let clock = SimulatedClock::new(START);
    let mut lp = twin_loop(clock.clone(), inputs);
    let periods = 150; // 2 s
    lp.run_ticks(periods * u64::from(TICKS_PER_PERIOD)).unwrap();
    let end = clock.now();
    let rec = lp.vibrotactors();
    assert_eq!(rec.dropped_edges(), 0);
    let from = START;
    let to = START.add_nanos(periods * 13_333_333);
    assert!(end >= to.add_nanos(0) || end.nanos_since(to) < 1_000_000);

    let low = rec.channel_summary(0, from, to);
    assert_eq!(low.rising_edges, 0, "Low is silent");
    assert_eq!(low.duty, 0.0);
    for (channel, duty) in [(1, 0.2), (2, 0.5)] {
        let s = rec.channel_summary(channel, from, to);
        let f = s.frequency_hz.expect("a carrier");
        println!(
            "channel {channel}: {f:.6} Hz, duty {:.4} %, {} pulses, period range {:?} ns",
            100.0 * s.duty,
            s.rising_edges,
            s.period_range_ns
        );
        assert!(within(f, 75.0, 0.01), "channel {channel}: {f} Hz");
        assert!(
            (s.duty - duty).abs() < 0.005,
            "channel {channel}: duty {}",
            s.duty
        );
        assert_eq!(s.rising_edges, periods, "one pulse per period");
    }
    // Punctual simulated wake-ups: every period equals the nominal tick (±1 ns rounding).
    let j = lp.jitter();
    assert_eq!(j.count(), periods * u64::from(TICKS_PER_PERIOD) - 1);
    assert!(j.max_period_ns().unwrap() - j.min_period_ns().unwrap() <= 1);
    assert_eq!(j.missed_ticks(), 0);
}

#[test]
fn late_wakeups_are_measured_and_the_carrier_holds() {
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([H, M, H]));
    let clock = SimulatedClock::new(START).with_latency(60_000, 42);
    let mut lp = twin_loop(clock.clone(), inputs);
    lp.run_ticks(3_000).unwrap();
    let to = START.add_nanos(149 * 13_333_333);
    for (channel, duty) in [(0, 0.5), (1, 0.2)] {
        let s = lp.vibrotactors().channel_summary(channel, START, to);
        assert!(within(s.frequency_hz.unwrap(), 75.0, 0.01), "{s:?}");
        // Edges move by at most the latency (60 µs = 0.45 % of a period).
        assert!((s.duty - duty).abs() < 0.006, "{s:?}");
    }
    let j = lp.jitter();
    println!(
        "with 0..60 µs wake-up latency: period {}..{} ns, p99 |deviation| <= {:?} ns, max lateness {} ns",
        j.min_period_ns().unwrap(),
        j.max_period_ns().unwrap(),
        j.p99_deviation_ns(),
        j.max_lateness_ns()
    );
    assert!(j.max_lateness_ns() <= 60_000 && j.max_lateness_ns() > 30_000);
    let p99 = j.p99_deviation_ns().unwrap();
    assert!(p99 > 10_000 && p99 <= 61_000, "p99 {p99}");
    assert!(j.max_period_ns().unwrap() <= 666_666 + 60_000);
    assert!(j.min_period_ns().unwrap() >= 666_666 - 60_000);
}

#[test]
fn a_stall_skips_ticks_instead_of_bursting() {
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([H, H, H]));
    let clock = SimulatedClock::new(START);
    let mut lp = twin_loop(clock.clone(), inputs);
    lp.run_ticks(10).unwrap();
    clock.advance(5_000_000); // the thread was descheduled for 5 ms
    lp.run_ticks(10).unwrap();
    let j = lp.jitter();
    // Woke at 6.0 + 5 ms = 11.0 ms, i.e. in tick 16: ticks 10..=15 are skipped, not replayed.
    assert_eq!(j.missed_ticks(), 6);
    // One write per wake-up (no burst), and the schedule continues on the original grid:
    // the last of the ten steps after the stall is tick 25.
    assert_eq!(lp.vibrotactors().writes(), 20);
    assert_eq!(clock.now(), START.add_nanos(25 * 13_333_333 / 20));
}

#[test]
fn safe_state_and_missing_colour_are_quiet_and_shutdown_ends_off() {
    let inputs = Arc::new(VibrationInputs::new());
    let clock = SimulatedClock::new(START);
    let mut lp = twin_loop(clock.clone(), inputs.clone());
    // Not yet active: silent even with levels.
    inputs.set_levels(Some([H, H, H]));
    lp.run_ticks(200).unwrap();
    assert!(lp.vibrotactors().edges().is_empty());
    inputs.set_active(true);
    lp.run_ticks(200).unwrap();
    assert!(!lp.vibrotactors().edges().is_empty());
    // Safe state in the middle of a pulse: off at the next tick, and stays off.
    let before = lp.vibrotactors().edges().len();
    inputs.set_active(false);
    lp.run_ticks(1).unwrap();
    assert_eq!(lp.outputs(), [false; 3]);
    lp.run_ticks(300).unwrap();
    assert!(lp.vibrotactors().edges().len() <= before + 3);
    assert_eq!(lp.vibrotactors().state(), [false; 3]);
    // Back on, then the finger leaves the image: silent.
    inputs.set_active(true);
    lp.run_ticks(40).unwrap();
    inputs.set_levels(None);
    lp.run_ticks(1).unwrap();
    let quiet_from = lp.vibrotactors().edges().len();
    lp.run_ticks(100).unwrap();
    assert_eq!(lp.vibrotactors().edges().len(), quiet_from);
    // Shutdown while rendering: `run` returns with everything off.
    inputs.set_levels(Some([H, M, H]));
    lp.run_ticks(7).unwrap();
    inputs.request_shutdown();
    lp.run().unwrap();
    assert_eq!(lp.vibrotactors().state(), [false; 3]);
}

#[test]
fn a_failing_output_stops_the_loop_with_its_kind() {
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([H, H, H]));
    let clock = SimulatedClock::new(START);
    let mut vibro = RecordingVibrotactors::new(clock.clone(), 1000);
    vibro.fail_from_write(50);
    let pattern = Pattern::new(PatternConfig::default()).unwrap();
    let mut lp = VibrationLoop::new(vibro, clock, pattern, 20, inputs).unwrap();
    let e = lp.run().unwrap_err();
    assert_eq!(e.kind, ErrorKind::Disconnected);
    assert_eq!(e.tick, 50);
    assert!(e.to_string().contains("disconnected"), "{e}");
}

#[test]
fn the_loop_runs_on_its_own_thread_until_shutdown() {
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    inputs.set_levels(Some([M, L, H]));
    let clock = SimulatedClock::new(START);
    let mut lp = twin_loop(clock.clone(), inputs.clone());
    let handle = std::thread::spawn(move || lp.run().map(|()| lp));
    while clock.now().nanos_since(START) < 1_000_000_000 {
        std::thread::yield_now();
    }
    inputs.request_shutdown();
    let lp = handle.join().unwrap().unwrap();
    assert_eq!(lp.vibrotactors().state(), [false; 3]);
    assert!(lp.jitter().count() > 1_000);
}

/// A colour sample that wobbles across the Low/Mid threshold of the red channel (85) by less than
/// the hysteresis band (±8) keeps the red vibrotactor's pattern unchanged; without hysteresis
/// the same wobble switches it.
#[test]
fn hysteresis_keeps_the_vibration_steady_on_a_boundary() {
    for (hysteresis, expect_steady) in [(8.0, true), (0.0, false)] {
        let inputs = Arc::new(VibrationInputs::new());
        inputs.set_active(true);
        let clock = SimulatedClock::new(START);
        let mut lp = twin_loop(clock.clone(), inputs.clone());
        let mut q = Quantizer::new(QuantizerConfig {
            hysteresis,
            ..QuantizerConfig::plain_rgb()
        })
        .unwrap();
        inputs.set_levels(Some(q.update([90, 200, 20]))); // red Mid
        let mut level_changes = 0;
        // 3 s of colour samples at 30 Hz, red 79..=91 (threshold 85), 20 loop ticks between.
        for i in 0..90u32 {
            let red = 79 + ((i * 5) % 13) as u8;
            let before = inputs.levels();
            inputs.set_levels(Some(q.update([red, 200, 20])));
            level_changes += u32::from(inputs.levels() != before);
            lp.run_ticks(33).unwrap();
        }
        let s = summarize(lp.vibrotactors().edges(), 0, START, clock.now());
        if expect_steady {
            assert_eq!(level_changes, 0);
            assert!((s.duty - 0.2).abs() < 0.01, "red stays Mid: {s:?}");
            let (lo, hi) = s.period_range_ns.unwrap();
            assert!(
                lo >= 13_333_000 && hi <= 13_334_000,
                "steady 75 Hz: {lo}..{hi}"
            );
        } else {
            assert!(level_changes > 10, "{level_changes}");
            assert!(s.duty < 0.18, "red drops to Low part of the time: {s:?}");
        }
    }
}
