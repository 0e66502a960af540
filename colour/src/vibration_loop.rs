//! The vibration driver loop: at a fixed tick (default 20 ticks per carrier period, 1.5 kHz at
//! 75 Hz) it sleeps to an absolute deadline on the injected [`Clock`], computes the pattern of the
//! current level triple and writes the three outputs. It goes quiet (all off) while the device is
//! in the safe state, while no colour is available, and on shutdown.
//!
//! Real-time rules: the tick allocates nothing, takes no lock and reads its inputs from atomics
//! ([`VibrationInputs`]); the only blocking call is the clock's absolute sleep.
//!
//! Timing: tick `k`'s deadline is `origin + k·P/N` computed exactly in integers (`P` the carrier
//! period in ns, `N` ticks per period), so ticks never drift against the carrier. The output held
//! from tick `k` to `k+1` is the pattern at the middle of that interval, so a level with duty `d`
//! is on for `round(d·N)` ticks of every period (exact for the default duties 0/20/50 % and
//! `N = 20`).

use std::sync::atomic::{AtomicBool, AtomicU8, Ordering};
use std::sync::Arc;

use thiserror::Error;
use videt_hal::{Clock, MonoTime, Vibrotactors, VIBROTACTORS};

use crate::jitter::PeriodJitter;
use crate::level::{decode_triple, encode_triple, LevelTriple};
use crate::pattern::Pattern;

/// Code stored when no colour is to be rendered.
const NO_LEVELS: u8 = u8::MAX;

/// The loop's inputs, shared lock-free with the threads that set them.
#[derive(Debug)]
pub struct VibrationInputs {
    levels: AtomicU8,
    active: AtomicBool,
    shutdown: AtomicBool,
}

impl Default for VibrationInputs {
    fn default() -> Self {
        VibrationInputs::new()
    }
}

impl VibrationInputs {
    /// Inputs that start quiet: no levels, not active, no shutdown requested.
    pub const fn new() -> VibrationInputs {
        VibrationInputs {
            levels: AtomicU8::new(NO_LEVELS),
            active: AtomicBool::new(false),
            shutdown: AtomicBool::new(false),
        }
    }
    /// The triple to render, or `None` for silence (e.g. the finger is outside the image).
    pub fn set_levels(&self, levels: Option<LevelTriple>) {
        let code = levels.map_or(NO_LEVELS, encode_triple);
        self.levels.store(code, Ordering::Release);
    }
    /// The triple being rendered, if any.
    pub fn levels(&self) -> Option<LevelTriple> {
        decode_triple(self.levels.load(Ordering::Acquire))
    }
    /// `false` puts the vibrotactors in the safe state (all off) until set `true` again.
    pub fn set_active(&self, active: bool) {
        self.active.store(active, Ordering::Release);
    }
    /// Whether rendering is allowed.
    pub fn is_active(&self) -> bool {
        self.active.load(Ordering::Acquire)
    }
    /// Ask the loop to switch everything off and return.
    pub fn request_shutdown(&self) {
        self.shutdown.store(true, Ordering::Release);
    }
    /// Whether shutdown was requested.
    pub fn shutdown_requested(&self) -> bool {
        self.shutdown.load(Ordering::Acquire)
    }
}

/// A rejected loop configuration.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("vibration loop: ticks_per_period = {0} is invalid; allowed: 2..=1000")]
pub struct LoopConfigError(pub u32);

/// A vibrotactor write failed; the loop tried to switch everything off and stopped.
#[derive(Debug, Clone, PartialEq, Error)]
#[error("vibrotactor write failed ({kind}) at tick {tick}")]
pub struct VibrationError {
    /// What kind of failure the device reported.
    pub kind: videt_hal::ErrorKind,
    /// The tick it happened at.
    pub tick: u64,
}

/// The driver loop over a vibrotactor device `V` and a clock `C`.
#[derive(Debug)]
pub struct VibrationLoop<V, C> {
    vibrotactors: V,
    clock: C,
    pattern: Pattern,
    ticks_per_period: u64,
    inputs: Arc<VibrationInputs>,
    origin: Option<MonoTime>,
    tick: u64,
    last_wake: Option<MonoTime>,
    outputs: [bool; VIBROTACTORS],
    jitter: PeriodJitter,
}

impl<V: Vibrotactors, C: Clock> VibrationLoop<V, C> {
    /// Default ticks per carrier period (1.5 kHz at 75 Hz).
    pub const DEFAULT_TICKS_PER_PERIOD: u32 = 20;

    /// A loop that has not started; `ticks_per_period` in `2..=1000`.
    pub fn new(
        vibrotactors: V,
        clock: C,
        pattern: Pattern,
        ticks_per_period: u32,
        inputs: Arc<VibrationInputs>,
    ) -> Result<Self, LoopConfigError> {
        if !(2..=1000).contains(&ticks_per_period) {
            return Err(LoopConfigError(ticks_per_period));
        }
        let nominal = pattern.period_ns() / u64::from(ticks_per_period);
        Ok(VibrationLoop {
            vibrotactors,
            clock,
            pattern,
            ticks_per_period: u64::from(ticks_per_period),
            inputs,
            origin: None,
            tick: 0,
            last_wake: None,
            outputs: [false; VIBROTACTORS],
            jitter: PeriodJitter::new(nominal),
        })
    }

    /// The nominal tick period, nanoseconds (rounded down; the schedule itself is exact).
    pub fn tick_period_ns(&self) -> u64 {
        self.pattern.period_ns() / self.ticks_per_period
    }

    /// Period statistics recorded so far.
    pub fn jitter(&self) -> &PeriodJitter {
        &self.jitter
    }

    /// The outputs last written.
    pub fn outputs(&self) -> [bool; VIBROTACTORS] {
        self.outputs
    }

    /// The device.
    pub fn vibrotactors(&self) -> &V {
        &self.vibrotactors
    }

    /// The device and the clock back.
    pub fn into_parts(self) -> (V, C) {
        (self.vibrotactors, self.clock)
    }

    /// Offset of tick `k` from the origin, nanoseconds (exact integer schedule).
    fn tick_offset_ns(&self, k: u64) -> u64 {
        let p = self.pattern.period_ns();
        let n = self.ticks_per_period;
        (k / n) * p + (k % n) * p / n
    }

    /// The index of the last tick whose deadline is at or before `offset_ns`.
    fn tick_at_offset(&self, offset_ns: u64) -> u64 {
        let p = self.pattern.period_ns();
        let n = self.ticks_per_period;
        let k = (offset_ns / p) * n + (offset_ns % p) * n / p;
        // Integer division may land one tick early; correct with a bounded step.
        if self.tick_offset_ns(k + 1) <= offset_ns {
            k + 1
        } else {
            k
        }
    }

    fn write(&mut self, outputs: [bool; VIBROTACTORS]) -> Result<(), VibrationError> {
        match self.vibrotactors.set_outputs(&outputs) {
            Ok(()) => {
                self.outputs = outputs;
                Ok(())
            }
            Err(e) => {
                let kind = videt_hal::Error::kind(&e);
                // Fail safe: try to leave everything off; the original error is what is reported.
                let _ = self.vibrotactors.set_outputs(&[false; VIBROTACTORS]);
                self.outputs = [false; VIBROTACTORS];
                Err(VibrationError {
                    kind,
                    tick: self.tick,
                })
            }
        }
    }

    /// One tick: sleep to its deadline, write the pattern (or silence), schedule the next tick
    /// (skipping ticks whose deadlines have already passed). Returns `false` once shutdown is
    /// requested (outputs are then off). **RT**: allocation-free.
    pub fn step(&mut self) -> Result<bool, VibrationError> {
        let origin = *self.origin.get_or_insert_with(|| self.clock.now());
        let deadline = origin.add_nanos(self.tick_offset_ns(self.tick));
        self.clock.sleep_until(deadline);
        let woke = self.clock.now();
        self.jitter.record_lateness(woke.nanos_since(deadline));
        if let Some(previous) = self.last_wake {
            self.jitter.record_period(woke.nanos_since(previous));
        }
        self.last_wake = Some(woke);
        // Woken after later ticks' deadlines (the thread was held up): render the tick that is
        // due now rather than replaying the missed ones.
        let due = self.tick_at_offset(woke.nanos_since(origin));
        if due > self.tick {
            self.jitter.record_missed(due - self.tick);
            self.tick = due;
        }

        if self.inputs.shutdown_requested() {
            self.write([false; VIBROTACTORS])?;
            return Ok(false);
        }
        let outputs = match (self.inputs.is_active(), self.inputs.levels()) {
            (true, Some(levels)) => {
                let mid_tick =
                    (self.tick_offset_ns(self.tick) + self.tick_offset_ns(self.tick + 1)) / 2;
                self.pattern.outputs(mid_tick, levels)
            }
            _ => [false; VIBROTACTORS],
        };
        self.write(outputs)?;

        self.tick += 1;
        Ok(true)
    }

    /// Run until shutdown is requested, then leave all outputs off. **RT** body.
    pub fn run(&mut self) -> Result<(), VibrationError> {
        while self.step()? {}
        Ok(())
    }

    /// Run at most `ticks` ticks (stops early on shutdown); for tests and measurements.
    pub fn run_ticks(&mut self, ticks: u64) -> Result<(), VibrationError> {
        for _ in 0..ticks {
            if !self.step()? {
                break;
            }
        }
        Ok(())
    }

    /// Switch everything off now (e.g. before dropping the loop without a shutdown tick).
    pub fn quiet(&mut self) -> Result<(), VibrationError> {
        self.write([false; VIBROTACTORS])
    }
}
