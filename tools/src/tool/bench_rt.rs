//! `videt bench-rt`: run the real control loop on the digital twin in real time and report its
//! wake-up latency, compute time and overruns, for comparison with `cyclictest` on the same
//! machine (see `docs/latency.md`).

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use clap::Args;
use serde::Serialize;
use videt_config::Config;

use videt_assembly::twin_rt::RealTimeTwin;
use videt_runtime::control_loop::{
    run_control_loop, start_hardware, LoopControl, LoopSettings, LoopStats,
};
use videt_runtime::cycle::WireZero;
use videt_runtime::histogram::Histogram;
use videt_runtime::snapshot::FixedSurface;
use videt_runtime::{rt, setup};

use super::ToolResult;

/// Measure the control loop's real-time behaviour on this machine.
#[derive(Debug, Args)]
pub struct BenchRtArgs {
    /// Loop rate, Hz (1000..=10000).
    #[arg(long, default_value_t = 1000)]
    pub rate: u32,
    /// How long to run, seconds.
    #[arg(long, default_value_t = 10.0)]
    pub seconds: f64,
    /// SCHED_FIFO priority of the loop (cyclictest's default comparison uses the same).
    #[arg(long, default_value_t = 80)]
    pub priority: u8,
    /// CPU to pin the loop to (-1: no pinning).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub cpu: i32,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

/// Percentiles in microseconds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Maximum.
    pub max: f64,
    /// Mean.
    pub mean: f64,
}

impl Percentiles {
    fn of(h: &Histogram) -> Percentiles {
        let us = |ns: u64| ns as f64 * 1e-3;
        Percentiles {
            p50: us(h.quantile_ns(0.5)),
            p99: us(h.quantile_ns(0.99)),
            p999: us(h.quantile_ns(0.999)),
            max: us(h.max_ns()),
            mean: h.mean_ns() * 1e-3,
        }
    }
}

/// The benchmark's result.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchRtReport {
    /// Loop rate, Hz.
    pub rate_hz: u32,
    /// Seconds run.
    pub seconds: f64,
    /// Periods run.
    pub cycles: u64,
    /// The loop ran SCHED_FIFO.
    pub fifo: bool,
    /// The loop was pinned.
    pub pinned: bool,
    /// Wake-up latency, µs.
    pub wake_latency_us: Percentiles,
    /// Compute time per period, µs.
    pub compute_us: Percentiles,
    /// Periods whose work ended after the next deadline.
    pub overruns: u64,
    /// Wake-ups later than one period (comparable with cyclictest's samples over the period).
    pub late_wakeups_over_period: u64,
}

/// Run the benchmark.
pub fn bench(args: &BenchRtArgs) -> Result<BenchRtReport, super::ToolError> {
    if !(1000..=10000).contains(&args.rate) {
        return Err(format!("--rate {}: must be in [1000, 10000] Hz", args.rate).into());
    }
    if !(args.seconds.is_finite() && args.seconds > 0.0 && args.seconds <= 3600.0) {
        return Err(format!("--seconds {}: must be in (0, 3600]", args.seconds).into());
    }
    let mut config = Config::default();
    config.control.rate_hz = args.rate;
    config.realtime.control_priority = args.priority;
    config.realtime.control_cpu = args.cpu;
    config.validate()?;
    let _ = rt::lock_memory();
    // As cyclictest does by default: keep the CPUs out of slow idle states while measuring.
    let _cpu_latency = match rt::hold_cpu_latency(0) {
        Ok(guard) => Some(guard),
        Err(e) => {
            eprintln!("warning: CPU wake-up latency not limited (/dev/cpu_dma_latency: {e})");
            None
        }
    };
    let rig = setup::rig(&config).map_err(|e| e.to_string())?;
    let scene = videt_assembly::twin_scene::wireman_wall_scene(&config, 3);
    let mut cycle = setup::control_cycle(&config, rig, WireZero::default(), true);
    let settings = LoopSettings {
        rate_hz: args.rate,
        duration_ns: Some((args.seconds * 1e9) as u64),
        max_consecutive_overruns: u32::MAX,
    };
    let (priority, cpu) = (args.priority, usize::try_from(args.cpu).ok());
    let handle = std::thread::Builder::new()
        .name("videt-bench-rt".into())
        .spawn(move || {
            let rt_report = rt::setup_control_thread(priority, cpu);
            let mut hw = RealTimeTwin::new(scene.twin);
            start_hardware(&mut hw)?;
            let mut stats = LoopStats::default();
            let stop = AtomicBool::new(false);
            let mut surface = FixedSurface(scene.wall);
            run_control_loop(
                &mut hw,
                &mut surface,
                &mut cycle,
                &settings,
                &mut LoopControl::stop_flag(&stop),
                &mut (),
                &mut stats,
            );
            Ok::<_, super::ToolError>((rt_report, stats))
        })?;
    let (rt_report, stats) = handle.join().map_err(|_| "the benchmark loop panicked")??;
    for w in &rt_report.warnings {
        eprintln!("warning: {w}");
    }
    let period_ns = 1_000_000_000 / u64::from(args.rate);
    Ok(BenchRtReport {
        rate_hz: args.rate,
        seconds: args.seconds,
        cycles: stats.cycles,
        fifo: rt_report.fifo,
        pinned: rt_report.pinned,
        wake_latency_us: Percentiles::of(&stats.latency),
        compute_us: Percentiles::of(&stats.compute),
        overruns: stats.overruns,
        late_wakeups_over_period: stats.latency.count_above(period_ns),
    })
}

/// Run `videt bench-rt`.
pub fn run(args: &BenchRtArgs) -> ToolResult {
    let r = bench(args)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let p = |x: &Percentiles| {
            format!(
                "p50 {:8.1}  p99 {:8.1}  p99.9 {:8.1}  max {:8.1} µs",
                x.p50, x.p99, x.p999, x.max
            )
        };
        println!(
            "control loop on the twin: {} Hz for {:.1} s, {} periods ({}{})",
            r.rate_hz,
            r.seconds,
            r.cycles,
            if r.fifo { "SCHED_FIFO" } else { "SCHED_OTHER" },
            if r.pinned { ", pinned" } else { "" }
        );
        println!("  wake-up latency  {}", p(&r.wake_latency_us));
        println!("  compute time     {}", p(&r.compute_us));
        println!(
            "  overruns {}; wake-ups later than one period {}",
            r.overruns, r.late_wakeups_over_period
        );
    }
    Ok(ExitCode::SUCCESS)
}
