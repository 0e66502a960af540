//! The per-reading and per-tick paths allocate nothing: window sampling (mean and median),
//! quantization, pattern evaluation and the vibration loop's tick on recording vibrotactors.
//! Checked with a counting global allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use videt_colour::level::Level::{High, Low, Mid};
use videt_colour::{
    Pattern, PatternConfig, Quantizer, QuantizerConfig, RecordingVibrotactors, SamplerConfig,
    SimulatedClock, VibrationInputs, VibrationLoop, WindowSampler, WindowStatistic,
};
use videt_control::SceneMap;
use videt_hal::{MonoTime, RgbFrame};

struct CountingAllocator;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Count only on the thread under test (the test harness allocates on its own threads).
    static COUNTING: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

fn count() {
    if COUNTING.with(|c| c.get()) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    }
}

// SAFETY: forwards to the system allocator; only counts calls.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

fn allocations_during(f: impl FnOnce()) -> u64 {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

#[test]
fn reading_and_ticking_allocate_nothing() {
    // The counter sees allocations on this thread.
    assert_eq!(
        allocations_during(|| {
            std::hint::black_box(vec![1u8; 10]);
        }),
        1
    );
    let (w, h) = (64u32, 48u32);
    let data = (0..w * h * 3).map(|i| (i * 37 % 251) as u8).collect();
    let frame = RgbFrame {
        width: w,
        height: h,
        data,
    };
    let map = SceneMap::new([0.0, 0.0], [0.2, 0.15], [w, h], 0.4, 0.08, [0.5, 5.0]).unwrap();
    let mut samplers = [WindowStatistic::Median, WindowStatistic::Mean].map(|statistic| {
        WindowSampler::new(SamplerConfig {
            window_px: 9,
            statistic,
        })
        .unwrap()
    });
    let mut quantizer = Quantizer::new(QuantizerConfig::default()).unwrap();
    let pattern = Pattern::new(PatternConfig::default()).unwrap();
    let inputs = Arc::new(VibrationInputs::new());
    inputs.set_active(true);
    let clock = SimulatedClock::new(MonoTime(0)).with_latency(20_000, 3);
    let vibro = RecordingVibrotactors::new(clock.clone(), 10_000);
    let mut lp = VibrationLoop::new(vibro, clock, pattern, 20, inputs.clone()).unwrap();

    let n = allocations_during(|| {
        for k in 0..2_000u32 {
            let x = 0.2 * (f64::from(k % 97) + 0.5) / 97.0;
            let y = 0.15 * (f64::from(k % 89) + 0.5) / 89.0;
            for s in &mut samplers {
                let rgb = s.sample_workspace(&frame, &map, x, y).unwrap();
                inputs.set_levels(Some(quantizer.update(rgb)));
            }
            let _ = samplers[0].sample_pixel(&frame, -1.0, 0.0); // error path too
            let _ = pattern.outputs(u64::from(k) * 123_457, [Low, Mid, High]);
            lp.step().unwrap();
        }
    });
    assert_eq!(n, 0, "allocations in the per-reading / per-tick path");
    assert!(!lp.vibrotactors().edges().is_empty());
}
