//! The Z-width: the stiffest wall rendered without sustained oscillation, against damping, per
//! control rate and tension sensor, on the wall of each of the paper's regions: a short
//! criterion bisected on a log scale, then a 10 s hold and release on the stiffest wall found.

use serde::Serialize;
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_control::FeltTally;

use super::region::Region;
use super::rig::{run, Experiment, Parts};
use super::settings::{renderings_compared, BenchPlan, Rendering, SensorSetup};
use super::wall::{hold_stats, pusher, region_wall};
use super::wall_feel::{feel_wall_in, WallFeel};

/// How a wall of given stiffness behaved while the operator held a push on it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WallVerdict {
    /// Wall stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Half the peak-to-peak penetration over the judged window, mm.
    pub oscillation_mm: f64,
    /// RMS thimble speed over the judged window, mm/s.
    pub rms_speed_mm_s: f64,
    /// Periods of the judged window out of contact.
    pub contact_lost: usize,
    /// The safety supervisor stayed in its normal state.
    pub safe: bool,
    /// No sustained oscillation (see [`ZWIDTH_CRITERION`]).
    pub stable: bool,
    /// What the finger felt beyond what was asked over the run (`docs/felt-force.md`).
    pub felt: FeltTally,
}

/// The Z-width's criterion, as printed with the results.
pub const ZWIDTH_CRITERION: &str =
    "the operator (hand 200 N/m) pushes 15 mm past a wall (P2; region A: facing \
the frame, B: a side wall, C: facing away) and holds; over the last 0.6 s of a 1.5 s hold the wall is stable when the \
penetration's half peak-to-peak stays below 0.1 mm, the RMS speed below 5 mm/s, the finger never \
leaves the wall and the safety supervisor never leaves its normal state";

/// Press on the wall facing the frame (region A) of stiffness `k` with damping `b` and judge it.
pub fn judge_wall(base: &Config, k: f64, b: f64, parts: Parts) -> Result<WallVerdict, String> {
    judge_wall_in(base, Region::A, k, b, parts)
}

/// Press on the wall of `region` of stiffness `k` with damping `b` and judge it.
pub fn judge_wall_in(
    base: &Config,
    region: Region,
    k: f64,
    b: f64,
    parts: Parts,
) -> Result<WallVerdict, String> {
    let (config, start, n, surface) = region_wall(base, region, k, b);
    let trace = run(&Experiment {
        config,
        surface,
        operator: pusher(start, n, &[0.015], &[0.0], 200.0),
        duration_s: 1.8,
        parts,
    })?;
    let hold = hold_stats(&trace, &surface, 1.2, 1.8);
    let safe = trace.final_safety == SafetyState::Normal && hold.periods > 0;
    Ok(WallVerdict {
        stiffness_n_per_m: k,
        oscillation_mm: hold.oscillation_mm,
        rms_speed_mm_s: hold.rms_speed_mm_s,
        contact_lost: hold.contact_lost,
        safe,
        stable: safe
            && hold.contact_lost == 0
            && hold.oscillation_mm < 0.1
            && hold.rms_speed_mm_s < 5.0,
        felt: trace.felt,
    })
}

/// The Z-width at one rate and sensor, for one damping.
#[derive(Debug, Clone, Serialize)]
pub struct ZWidthRow {
    /// The region of the wall's normal at the thimble's start.
    pub region: Region,
    /// The parts' model (the configured parts' timing, or ideal parts for reference).
    pub parts: Parts,
    /// Control rate, Hz.
    pub rate_hz: u32,
    /// The tension sensor.
    pub sensor: String,
    /// The PI gains' fraction the sensor allows (1 = the configured gains).
    pub tension_gain_scale: f64,
    /// The rendering (before, or as configured).
    pub rendering: Rendering,
    /// Wall damping, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Stiffest stable wall found, N/m (`None`: not even the softest one).
    pub max_stable_n_per_m: Option<f64>,
    /// Softest unstable wall found, N/m (`None`: stable up to the configuration's bound).
    pub min_unstable_n_per_m: Option<f64>,
    /// Every wall tried.
    pub tried: Vec<WallVerdict>,
    /// The stiffest stable wall's 10 s hold and release (and the stiffer ones that failed it).
    pub held: Vec<WallFeel>,
}

/// Softest and stiffest walls the Z-width search considers, N/m (the configuration allows
/// stiffness up to 20 000 N/m).
pub const ZWIDTH_RANGE_N_PER_M: (f64, f64) = (100.0, 20_000.0);

/// What a Z-width search found.
#[derive(Debug, Clone, PartialEq)]
pub struct ZWidthSearch {
    /// Stiffest stable wall, N/m (`None`: not even the softest one).
    pub max_stable_n_per_m: Option<f64>,
    /// Softest unstable wall, N/m (`None`: stable up to the configuration's bound).
    pub min_unstable_n_per_m: Option<f64>,
    /// Every wall tried, in order.
    pub tried: Vec<WallVerdict>,
    /// The long holds tried on the stiffest walls the short criterion passed, in order.
    pub held: Vec<WallFeel>,
}

/// How many times the Z-width steps down from the short criterion's stiffest wall when it fails
/// the 10 s hold and release, and by what factor each time.
const HOLD_STEPS_DOWN: (u32, f64) = (6, 0.85);

/// The short criterion's stiffest stable wall, confirmed by a 10 s hold and release or stepped
/// down until one passes.
fn confirm_by_holding(
    base: &Config,
    region: Region,
    b: f64,
    parts: Parts,
    search: &mut ZWidthSearch,
) -> Result<(), String> {
    let Some(mut k) = search.max_stable_n_per_m else {
        return Ok(());
    };
    for _ in 0..=HOLD_STEPS_DOWN.0 {
        let held = feel_wall_in(base, region, k, b, parts)?;
        search.held.push(held);
        if held.stable {
            search.max_stable_n_per_m = Some(k);
            return Ok(());
        }
        search.min_unstable_n_per_m = Some(k);
        k *= HOLD_STEPS_DOWN.1;
        if k < ZWIDTH_RANGE_N_PER_M.0 {
            break;
        }
    }
    search.max_stable_n_per_m = None;
    Ok(())
}

/// Find the largest stable stiffness: bisection on a log scale with the short criterion
/// (stability is taken to be monotonic in the stiffness, which every tried wall is recorded to
/// check), then the 10 s hold and release on the stiffest wall found, stepping down until one
/// passes.
pub fn zwidth(
    base: &Config,
    region: Region,
    b: f64,
    steps: u32,
    parts: Parts,
) -> Result<ZWidthSearch, String> {
    let mut search = zwidth_short(base, region, b, steps, parts)?;
    confirm_by_holding(base, region, b, parts, &mut search)?;
    Ok(search)
}

fn zwidth_short(
    base: &Config,
    region: Region,
    b: f64,
    steps: u32,
    parts: Parts,
) -> Result<ZWidthSearch, String> {
    let (lo_k, hi_k) = ZWIDTH_RANGE_N_PER_M;
    let mut tried = Vec::new();
    let hi = judge_wall_in(base, region, hi_k, b, parts)?;
    tried.push(hi);
    if hi.stable {
        return Ok(ZWidthSearch {
            max_stable_n_per_m: Some(hi_k),
            min_unstable_n_per_m: None,
            tried,
            held: Vec::new(),
        });
    }
    let lo = judge_wall_in(base, region, lo_k, b, parts)?;
    tried.push(lo);
    if !lo.stable {
        return Ok(ZWidthSearch {
            max_stable_n_per_m: None,
            min_unstable_n_per_m: Some(lo_k),
            tried,
            held: Vec::new(),
        });
    }
    let (mut stable, mut unstable) = (lo_k, hi_k);
    for _ in 0..steps {
        let mid = (stable * unstable).sqrt();
        let v = judge_wall_in(base, region, mid, b, parts)?;
        tried.push(v);
        if v.stable {
            stable = mid;
        } else {
            unstable = mid;
        }
    }
    Ok(ZWidthSearch {
        max_stable_n_per_m: Some(stable),
        min_unstable_n_per_m: Some(unstable),
        tried,
        held: Vec::new(),
    })
}

/// The Z-width table: every sensor (or the configured one) x rate x damping.
pub fn zwidth_sweep(base: &Config, plan: &BenchPlan) -> Result<Vec<ZWidthRow>, String> {
    let sensors: Vec<SensorSetup> = if plan.all_sensors {
        SensorSetup::SUPPORTED.to_vec()
    } else {
        vec![SensorSetup::of(base)]
    };
    let mut rates = vec![1000u32];
    if plan.highest_rate {
        let highest = videt_assembly::bus_budget::max_rate_hz(base).min(10_000);
        if highest > 1000 {
            rates.push(highest);
        }
    }
    // The configured sensor on ideal parts first: the reference the parts' timing is judged by.
    let mut runs = vec![(Region::A, Parts::Ideal, SensorSetup::of(base), 1000u32)];
    for sensor in &sensors {
        for &rate in &rates {
            runs.push((Region::A, Parts::Faithful, *sensor, rate));
        }
    }
    // The side wall and the wall facing away, on the configured parts.
    for region in [Region::B, Region::C] {
        runs.push((region, Parts::Faithful, SensorSetup::of(base), 1000));
    }
    let mut rows = Vec::new();
    for (region, parts, sensor, rate) in runs {
        let mut config = base.clone();
        sensor.apply(&mut config);
        config.control.rate_hz = rate;
        let scale = match videt_runtime::tension_budget::plan(&config) {
            Ok(videt_runtime::tension_budget::TensionLoopPlan::Full(_)) => 1.0,
            Ok(videt_runtime::tension_budget::TensionLoopPlan::Degraded { scale, .. }) => scale,
            Err(e) => return Err(format!("{}: {e}", sensor.label())),
        };
        let renderings = if region == Region::A {
            renderings_compared(base)
        } else {
            vec![Rendering::of(&base.control)]
        };
        for rendering in renderings {
            rendering.apply(&mut config);
            for &b in plan.damping_n_s_per_m {
                let found = zwidth(&config, region, b, plan.zwidth_steps, parts)?;
                rows.push(ZWidthRow {
                    region,
                    parts,
                    rate_hz: rate,
                    sensor: match parts {
                        Parts::Ideal => "instant".into(),
                        Parts::Faithful => sensor.label(),
                    },
                    tension_gain_scale: scale,
                    rendering,
                    damping_n_s_per_m: b,
                    max_stable_n_per_m: found.max_stable_n_per_m,
                    min_unstable_n_per_m: found.min_unstable_n_per_m,
                    tried: found.tried,
                    held: found.held,
                });
            }
        }
    }
    Ok(rows)
}
