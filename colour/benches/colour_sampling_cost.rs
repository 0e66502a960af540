//! Cost of the per-reading colour work: window sampling (mean vs median, 7x7), quantization with
//! hysteresis, and one tick's pattern evaluation.
//!
//! `cargo bench -p videt-colour --bench colour_sampling_cost`

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use videt_colour::level::Level::{High, Low, Mid};
use videt_colour::{
    Pattern, PatternConfig, Quantizer, QuantizerConfig, SamplerConfig, WindowSampler,
    WindowStatistic,
};
use videt_hal::RgbFrame;

fn frame() -> RgbFrame {
    let (w, h) = (450u32, 375u32);
    let mut data = Vec::with_capacity((3 * w * h) as usize);
    for v in 0..h {
        for u in 0..w {
            data.extend_from_slice(&[
                (u % 256) as u8,
                (v % 256) as u8,
                ((u * 7 + v * 3) % 256) as u8,
            ]);
        }
    }
    RgbFrame {
        width: w,
        height: h,
        data,
    }
}

fn bench(c: &mut Criterion) {
    let f = frame();
    for (name, statistic) in [
        ("sample_7x7_median", WindowStatistic::Median),
        ("sample_7x7_mean", WindowStatistic::Mean),
    ] {
        let mut s = WindowSampler::new(SamplerConfig {
            window_px: 7,
            statistic,
        })
        .unwrap();
        c.bench_function(name, |b| {
            b.iter(|| s.sample_pixel(black_box(&f), black_box(200.5), black_box(150.5)))
        });
    }
    for (name, config) in [
        ("quantize_chromaticity", QuantizerConfig::default()),
        ("quantize_plain_rgb", QuantizerConfig::plain_rgb()),
    ] {
        let mut q = Quantizer::new(config).unwrap();
        let mut k = 0u8;
        c.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(37);
                q.update(black_box([k, 255 - k, k / 2]))
            })
        });
    }
    let p = Pattern::new(PatternConfig::default()).unwrap();
    let mut t = 0u64;
    c.bench_function("pattern_outputs", |b| {
        b.iter(|| {
            t += 666_666;
            p.outputs(black_box(t), black_box([Low, Mid, High]))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
