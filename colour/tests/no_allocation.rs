//! The per-reading and per-tick paths allocate nothing: window sampling (mean and median),
//! quantization, pattern evaluation and the vibration loop's tick on recording vibrotactors.
//! Checked with a counting global allocator.

use std::sync::Arc;

use videt_colour::level::Level::{High, Low, Mid};
use videt_colour::{
    Pattern, PatternConfig, Quantizer, QuantizerConfig, RecordingVibrotactors, SamplerConfig,
    SimulatedClock, VibrationInputs, VibrationLoop, WindowSampler, WindowStatistic,
};
use videt_control::SceneMap;
use videt_hal::{MonoTime, RgbFrame};

#[global_allocator]
static GLOBAL: videt_testkit::CountingAllocator = videt_testkit::CountingAllocator;

fn allocations_during(f: impl FnOnce()) -> u64 {
    videt_testkit::count_allocations(f).1.allocations
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
