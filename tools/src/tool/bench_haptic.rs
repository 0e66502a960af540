//! `videt bench-haptic`: the haptic fidelity of a configuration, measured on the timing-faithful
//! twin — rendered vs programmed stiffness (P1, P2, regions A/B/C), Z-width against damping per
//! tension sensor and rate, penetration and pop-through at the wearer's push (see
//! `docs/haptic-bench.md`).

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use videt_config::Config;

use crate::haptic_bench::{plots, run_bench, BenchPlan, BenchReport};

use super::ToolResult;

/// Measure rendered stiffness, Z-width and pop-through on the twin.
#[derive(Debug, Args)]
pub struct BenchHapticArgs {
    /// Configuration to measure (default: the built-in defaults, those of
    /// `config/videt.example.toml`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A few points of each sweep only (seconds instead of minutes).
    #[arg(long)]
    pub quick: bool,
    /// Depth of the relief feature the finger must not push through, mm.
    #[arg(long, default_value_t = 5.0)]
    pub feature_mm: f64,
    /// Write the figures (stiffness.png, zwidth.png, pop_through.png) into this directory.
    #[arg(long)]
    pub plots: Option<PathBuf>,
    /// Print JSON (every row, every wall tried, the configuration).
    #[arg(long)]
    pub json: bool,
}

/// Run the bench.
pub fn run(args: &BenchHapticArgs) -> ToolResult {
    if !(args.feature_mm.is_finite() && args.feature_mm > 0.0) {
        return Err(format!("--feature-mm {} must be > 0", args.feature_mm).into());
    }
    let (config, origin) = match &args.config {
        Some(path) => (Config::load(path)?, path.display().to_string()),
        None => (Config::default(), "defaults".to_string()),
    };
    let plan = if args.quick {
        BenchPlan::QUICK
    } else {
        BenchPlan::FULL
    };
    let report = run_bench(&config, &origin, &plan, args.feature_mm)?;
    if let Some(dir) = &args.plots {
        for path in plots::write_all(dir, &report)? {
            eprintln!("wrote {}", path.display());
        }
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{}", render_text(&report));
    }
    Ok(ExitCode::SUCCESS)
}

/// "before", or "now" for the configured rendering.
fn rendering_label(r: &crate::haptic_bench::Rendering) -> &'static str {
    if *r == crate::haptic_bench::Rendering::BEFORE {
        "before"
    } else {
        "now"
    }
}

fn opt_k(k: Option<f64>) -> String {
    k.map_or_else(|| "-".into(), |k| format!("{k:.0}"))
}

/// The report as tables.
pub fn render_text(r: &BenchReport) -> String {
    use std::fmt::Write;
    let c = &r.control;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "haptic bench on the twin ({}): {} Hz, K {} N/m, B {} N·s/m, t {}..{} N, tension sensor {}",
        r.config_origin,
        c.rate_hz,
        c.stiffness_n_per_m,
        c.damping_n_s_per_m,
        c.t_min_n,
        c.t_max_n,
        r.sensor.label()
    );
    let _ = writeln!(
        s,
        "\nrendered stiffness (secant between pushes of 10 and 25 mm with a 400 N/m hand)"
    );
    let _ = writeln!(
        s,
        "  alg  polar  azim  region  K rendered  ratio   settled  safety"
    );
    for row in &r.stiffness {
        let _ = writeln!(
            s,
            "  {:<3} {:>5.0}° {:>4.0}°  {:<6?} {:>9.0}  {:>6.3}   {:<7}  {}",
            row.algorithm,
            row.polar_deg,
            row.azimuth_deg,
            row.region,
            row.rendered_n_per_m,
            row.ratio,
            if row.settled { "yes" } else { "no" },
            row.safety
        );
    }
    for algorithm in ["P1", "P2"] {
        for region in [
            crate::haptic_bench::Region::A,
            crate::haptic_bench::Region::B,
            crate::haptic_bench::Region::C,
        ] {
            let ratios: Vec<f64> = r
                .stiffness
                .iter()
                .filter(|x| x.algorithm == algorithm && x.region == region && x.ratio.is_finite())
                .map(|x| x.ratio)
                .collect();
            if let Some(m) = median(&ratios) {
                let lo = ratios.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let _ = writeln!(
                    s,
                    "  {algorithm} region {region:?}: ratio median {m:.3}, range {lo:.3}..{hi:.3} over {} normals",
                    ratios.len()
                );
            }
        }
    }
    let _ = writeln!(
        s,
        "  felt force over every stiffness and Z-width run: {}",
        r.felt
    );
    let _ = writeln!(s, "\nZ-width: {}", r.zwidth_criterion);
    let _ = writeln!(s, "  and then: {}", r.hold_criterion);
    let now = crate::haptic_bench::Rendering::of(c);
    let _ = writeln!(
        s,
        "  renderings: before = {}; now = {}",
        crate::haptic_bench::Rendering::BEFORE.label(),
        now.label()
    );
    let _ = writeln!(
        s,
        "  region  parts     sensor                  rate    PI gains  rendering  B N·s/m  stable K  unstable K  (N/m)"
    );
    for row in &r.zwidth {
        let _ = writeln!(
            s,
            "  {:<6}  {:<9} {:<22} {:>5} Hz  x{:<6.3} {:<9} {:>7.1}  {:>8}  {:>10}",
            format!("{:?}", row.region),
            format!("{:?}", row.parts).to_lowercase(),
            row.sensor,
            row.rate_hz,
            row.tension_gain_scale,
            rendering_label(&row.rendering),
            row.damping_n_s_per_m,
            opt_k(row.max_stable_n_per_m),
            opt_k(row.min_unstable_n_per_m)
        );
    }
    if !r.feel.is_empty() {
        let _ = writeln!(
            s,
            "\nthe wall's feel (P2, wall facing the frame, B {} N·s/m): push 15 mm, hold 10 s, release",
            c.damping_n_s_per_m
        );
        let _ = writeln!(
            s,
            "  rendering  K N/m  rendered/K  onset ms  returned/in (mJ)       hold ±mm  leaves ms  again  stable"
        );
        for row in &r.feel {
            let f = &row.feel;
            let _ = writeln!(
                s,
                "  {:<9} {:>6.0}  {:>10.3}  {:>8}  {:>5.3} ({:.2}/{:.2})  {:>9.4}  {:>9}  {:>5}  {}",
                rendering_label(&row.rendering),
                f.stiffness_n_per_m,
                row.stiffness_ratio,
                f.onset_delay_ms.map_or_else(|| "-".into(), |d| format!("{d:.1}")),
                f.returned_ratio,
                f.energy_returned_mj,
                f.energy_in_mj,
                f.hold_oscillation_mm,
                f.leaves_after_ms.map_or_else(|| "never".into(), |d| format!("{d:.0}")),
                f.touches_again,
                if f.stable { "yes" } else { "no" }
            );
        }
    }
    let p = &r.pop_through;
    let _ = writeln!(
        s,
        "\npenetration at K {} N/m (wall facing the frame, P2); relief feature {} mm",
        p.stiffness_n_per_m, p.feature_depth_mm
    );
    let _ = writeln!(s, "  push N  wall force N  penetration mm  max tension N");
    for row in &p.pushes {
        let _ = writeln!(
            s,
            "  {:>6.2}  {:>12.2}  {:>14.2}  {:>13.2}{}{}",
            row.push_n,
            row.wall_force_n,
            row.penetration_mm,
            row.max_tension_n,
            if row.saturated { "  saturated" } else { "" },
            if row.popped_through {
                "  through the feature"
            } else {
                ""
            }
        );
    }
    let _ = writeln!(
        s,
        "  the wearer's push ({:.1} N): {:.2} mm; pops through the {} mm feature from {}",
        p.wearer_push_n,
        p.wearer_penetration_mm,
        p.feature_depth_mm,
        p.pop_through_push_n
            .map_or_else(|| "no push tried".into(), |f| format!("{f:.1} N"))
    );
    s
}

fn median(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len().is_multiple_of(2) {
        (v[m - 1] + v[m]) / 2.0
    } else {
        v[m]
    })
}
