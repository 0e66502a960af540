//! The wall as the finger meets it, leans on it and lets it go: a 15 mm push by the bench's
//! operator (hand 200 N/m), a 10 s hold and a release, on one wall facing the frame (region A,
//! P2). It judges what the Z-width's short criterion cannot see (a limit cycle that builds up over
//! seconds, a wall that kicks the finger off or catches it again on release) and measures what
//! the finger feels of the rendering: how late the force rises when the finger touches, and how
//! much of the energy the finger put into the wall comes back when it leaves.
//!
//! The bench measures the feel at several stiffnesses, before and with the configured rendering,
//! each beside the stiffness rendered along the frame's axis.

use serde::Serialize;
use videt_config::Config;
use videt_control::safety::SafetyState;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

use super::region::Region;
use super::rig::{run, Experiment, Parts, Trace};
use super::settings::{renderings_compared, BenchPlan, Rendering};
use super::stiffness::secant_stiffness;
use super::wall::{hold_stats, region_wall, SURFACE_GAP_M};
use videt_control::surface::Plane;

/// How long the operator holds the push, seconds.
pub const HOLD_S: f64 = 10.0;
/// How far past the wall the operator's hand pushes, metres.
const PUSH_M: f64 = 0.015;
/// The operator's hand stiffness (the Z-width's operator), N/m.
const HAND_N_PER_M: f64 = 200.0;
/// The push and the release each take this long, seconds.
const MOVE_S: f64 = 0.3;
/// The hand waits this much longer than the forces' start-up ramp (`control.ramp_down_s`)
/// before pushing, seconds.
const SETTLE_AFTER_RAMP_S: f64 = 0.3;

/// When the hand starts to push and to withdraw, seconds from the start.
#[derive(Debug, Clone, Copy)]
struct Script {
    push_at_s: f64,
    release_at_s: f64,
}

impl Script {
    fn for_config(config: &Config) -> Script {
        let push_at_s = config.control.ramp_down_s + SETTLE_AFTER_RAMP_S;
        Script {
            push_at_s,
            release_at_s: push_at_s + MOVE_S + HOLD_S,
        }
    }
}
/// How long the bench watches after the release starts.
const AFTER_RELEASE_S: f64 = 1.2;
/// The judged window: the last second of the hold.
const HOLD_WINDOW_S: f64 = 1.0;
/// The onset delay is fitted over this long after the first contact, seconds.
const ONSET_WINDOW_S: f64 = 0.05;
/// Largest onset delay tried by the fit, seconds.
const ONSET_MAX_S: f64 = 0.02;

/// The long-hold criterion, as printed with the results.
pub const HOLD_CRITERION: &str = "the same operator pushes 15 mm past the wall, holds 10 s and \
withdraws: over the last second of the hold the penetration's half peak-to-peak stays below 0.1 mm \
and the RMS speed below 5 mm/s with the finger on the wall; on release the finger leaves the wall \
within 0.5 s and does not touch it again; the safety supervisor never leaves its normal state";

/// What a push, a 10 s hold and a release on a wall showed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WallFeel {
    /// Programmed stiffness K, N/m.
    pub stiffness_n_per_m: f64,
    /// Wall damping B, N·s/m.
    pub damping_n_s_per_m: f64,
    /// Half the peak-to-peak penetration over the hold's last second, mm.
    pub hold_oscillation_mm: f64,
    /// RMS thimble speed over the hold's last second, mm/s.
    pub hold_rms_speed_mm_s: f64,
    /// Periods of the hold's last second out of contact.
    pub hold_contact_lost: usize,
    /// How long after the hand starts withdrawing the finger leaves the wall, ms.
    pub leaves_after_ms: Option<f64>,
    /// Times the finger touched the wall again after leaving it.
    pub touches_again: usize,
    /// Delay of the wall's force behind the programmed law `K d - B v_n` as the finger first
    /// touches (the shift that best fits one to the other over the first 50 ms), ms.
    pub onset_delay_ms: Option<f64>,
    /// Energy the finger put into the wall over the whole contact (push, hold, release), mJ.
    pub energy_in_mj: f64,
    /// Energy the wall gave back to the finger over the same contact, mJ.
    pub energy_returned_mj: f64,
    /// `energy_returned / energy_in` over the closed cycle: a passive wall gives back at most
    /// what it took (at most 1); above 1 it pushed the finger out with energy of its own.
    pub returned_ratio: f64,
    /// The safety supervisor stayed in its normal state.
    pub safe: bool,
    /// The hold and the release pass [`HOLD_CRITERION`].
    pub stable: bool,
}

/// The operator: still until the forces ramped up, to 15 mm past the wall over 0.3 s, a 10 s
/// hold, back to the start over 0.3 s.
fn push_hold_release(script: Script, start: Vec3, n: Vec3, gap_m: f64) -> VirtualOperator {
    let pressed = start - n * (gap_m + PUSH_M);
    let at = |time_s: f64, target_m: Vec3| Waypoint { time_s, target_m };
    VirtualOperator::new(
        vec![
            at(0.0, start),
            at(script.push_at_s, start),
            at(script.push_at_s + MOVE_S, pressed),
            at(script.release_at_s, pressed),
            at(script.release_at_s + MOVE_S, start),
        ],
        HAND_N_PER_M,
        4.0,
    )
}

/// Push, hold and release the wall facing the frame (region A) of stiffness `k` and damping `b`
/// with `base`'s parts and tension loop, and judge it.
pub fn feel_wall(base: &Config, k: f64, b: f64, parts: Parts) -> Result<WallFeel, String> {
    feel_wall_in(base, Region::A, k, b, parts)
}

/// [`feel_wall`] on the wall of `region` ([`Region::wall_normal`]).
pub fn feel_wall_in(
    base: &Config,
    region: Region,
    k: f64,
    b: f64,
    parts: Parts,
) -> Result<WallFeel, String> {
    let (config, start, n, surface) = region_wall(base, region, k, b);
    let script = Script::for_config(&config);
    let trace = run(&Experiment {
        config: config.clone(),
        surface,
        operator: push_hold_release(script, start, n, SURFACE_GAP_M),
        duration_s: script.release_at_s + AFTER_RELEASE_S,
        parts,
    })?;
    Ok(judge(&trace, &surface, &config, script))
}

fn judge(trace: &Trace, surface: &Plane, config: &Config, script: Script) -> WallFeel {
    let release_at_s = script.release_at_s;
    let n = surface.normal();
    let depth = |p: &Vec3| -surface.signed_distance_m(p);
    let (k, b) = (
        config.control.stiffness_n_per_m,
        config.control.damping_n_s_per_m,
    );
    let hold = hold_stats(trace, surface, release_at_s - HOLD_WINDOW_S, release_at_s);
    let hold_oscillation_mm = if hold.periods > 0 {
        hold.oscillation_mm
    } else {
        f64::NAN
    };
    // The release: when the finger leaves, and whether it comes back.
    let mut leaves_at = None;
    let mut touches_again = 0;
    let mut in_contact = true;
    for s in trace.window(release_at_s, f64::INFINITY) {
        let touching = depth(&s.position_m) > 0.0;
        if in_contact && !touching {
            leaves_at.get_or_insert(s.time_s);
        } else if !in_contact && touching {
            touches_again += 1;
        }
        in_contact = touching;
    }
    let leaves_after_ms = leaves_at.map(|t| (t - release_at_s) * 1e3);
    // Energy through the wall along its normal over the whole contact, from the first touch to
    // the finger leaving after the release (a closed cycle: depth 0 to 0, so the wires' floor
    // tension does no net work): what the finger put in, and what the wall gave back.
    let left_at = leaves_at.unwrap_or(f64::INFINITY);
    let (mut energy_in, mut energy_out) = (0.0, 0.0);
    for w in trace.samples.windows(2) {
        let (s, next) = (&w[0], &w[1]);
        if s.time_s > left_at || depth(&s.position_m) <= 0.0 {
            continue;
        }
        let power = s.wire_force_n.dot(&n) * s.velocity_m_s.dot(&n) * (next.time_s - s.time_s);
        if power > 0.0 {
            energy_out += power;
        } else {
            energy_in -= power;
        }
    }
    let safe = trace.final_safety == SafetyState::Normal && hold.periods > 0;
    let stable = safe
        && hold.contact_lost == 0
        && hold_oscillation_mm < 0.1
        && hold.rms_speed_mm_s < 5.0
        && leaves_after_ms.is_some_and(|ms| ms <= 500.0)
        && touches_again == 0;
    WallFeel {
        stiffness_n_per_m: k,
        damping_n_s_per_m: b,
        hold_oscillation_mm,
        hold_rms_speed_mm_s: hold.rms_speed_mm_s,
        hold_contact_lost: hold.contact_lost,
        leaves_after_ms,
        touches_again,
        onset_delay_ms: onset_delay_s(trace, surface, k, b).map(|s| s * 1e3),
        energy_in_mj: energy_in * 1e3,
        energy_returned_mj: energy_out * 1e3,
        returned_ratio: energy_out / energy_in,
        safe,
        stable,
    }
}

/// The shift of the wall's normal force behind the programmed law `K d - B v_n` over the first
/// 50 ms of contact: for each shift (whole periods up to 20 ms), the least-squares fit of the
/// force to the shifted law plus a constant (the wires' floor tension); the best fit's shift.
fn onset_delay_s(trace: &Trace, surface: &Plane, k: f64, b: f64) -> Option<f64> {
    let n = surface.normal();
    let samples = &trace.samples;
    let first = samples
        .iter()
        .position(|s| -surface.signed_distance_m(&s.position_m) > 0.0)?;
    let programmed: Vec<f64> = samples
        .iter()
        .map(|s| {
            let d = -surface.signed_distance_m(&s.position_m);
            if d > 0.0 {
                (k * d - b * s.velocity_m_s.dot(&n)).max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    let t0 = samples[first].time_s;
    let end = samples
        .iter()
        .position(|s| s.time_s >= t0 + ONSET_WINDOW_S)?;
    let period = (samples[end].time_s - t0) / (end - first) as f64;
    let max_shift = (ONSET_MAX_S / period).round() as usize;
    let residual = |shift: usize| {
        let pairs = (first..end).map(|i| (samples[i].wire_force_n.dot(&n), programmed[i - shift]));
        let m = (end - first) as f64;
        let offset = pairs.clone().map(|(f, p)| f - p).sum::<f64>() / m;
        pairs.map(|(f, p)| (f - p - offset).powi(2)).sum::<f64>()
    };
    let residuals: Vec<f64> = (0..=max_shift.min(first)).map(residual).collect();
    let (best, _) = residuals
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))?;
    // A parabola through the best shift and its neighbours: the delay between periods.
    let fraction = match (best.checked_sub(1), residuals.get(best + 1)) {
        (Some(before), Some(&after)) => {
            let (a, b, c) = (residuals[before], residuals[best], after);
            let curvature = a - 2.0 * b + c;
            if curvature > 0.0 {
                (0.5 * (a - c) / curvature).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        }
        _ => 0.0,
    };
    Some((best as f64 + fraction).max(0.0) * period)
}

/// The wall as the finger feels it at one stiffness and integral gate.
#[derive(Debug, Clone, Serialize)]
pub struct FeelRow {
    /// The rendering (before, or as configured).
    pub rendering: Rendering,
    /// The push, hold and release (onset delay, energy returned, the hold's stability).
    pub feel: WallFeel,
    /// Rendered / programmed stiffness along the frame's axis (P2, region A; the secant of the
    /// stiffness sweep).
    pub stiffness_ratio: f64,
}

/// The wall's feel at the plan's stiffnesses and the configured one, before and with the
/// configured rendering, at the configured damping.
pub fn feel_sweep(base: &Config, plan: &BenchPlan) -> Result<Vec<FeelRow>, String> {
    let mut stiffnesses = plan.feel_stiffness_n_per_m.to_vec();
    stiffnesses.push(base.control.stiffness_n_per_m);
    stiffnesses.sort_by(f64::total_cmp);
    stiffnesses.dedup();
    let axis = Vec3::new(0.0, 0.0, -1.0);
    let mut rows = Vec::new();
    for rendering in renderings_compared(base) {
        for &k in &stiffnesses {
            let mut config = base.clone();
            rendering.apply(&mut config);
            config.control.stiffness_n_per_m = k;
            config.control.algorithm = "P2".into();
            let feel = feel_wall(
                &config,
                k,
                config.control.damping_n_s_per_m,
                Parts::Faithful,
            )?;
            let (rendered, ..) = secant_stiffness(&config, axis)?;
            rows.push(FeelRow {
                rendering,
                feel,
                stiffness_ratio: rendered / k,
            });
        }
    }
    Ok(rows)
}
