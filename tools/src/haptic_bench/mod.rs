//! The haptic fidelity bench: what the wearer's finger feels, measured on the timing-faithful
//! twin (the CiA 402 drives' per-mille torque and SYNC timing, the configured strain-gauge
//! converter's rate, filter and quantization) with the real control cycle.
//!
//! - **Stiffness**: the stiffness rendered by P1 and P2 against the programmed one, over
//!   surface normals in the paper's regions A, B and C (section 5, Figs 14-15).
//! - **Z-width**: the stiffest wall rendered without sustained oscillation, against damping,
//!   per control rate and tension sensor.
//! - **Pop-through**: the penetration at the wearer's pushing force, and the force the device
//!   can hold before a wire saturates.
//!
//! Every experiment is a run of the control loop on the twin's simulated clock: deterministic
//! (the same configuration gives the same figures) and independent of the machine's load.

pub mod plots;
pub mod rig;
mod wall;
pub mod wall_feel;
pub mod zwidth;

use serde::Serialize;
use videt_config::{Ads1220Mode, Config, TensionAdc};
use videt_control::safety::SafetyState;
use videt_control::surface::Plane;
use videt_control::FeltTally;
use videt_sim::{Vec3, VirtualOperator, Waypoint};

use rig::{run, start_position, Experiment, Parts, Trace};
use wall_feel::{feel_wall, WallFeel};
pub use zwidth::{
    judge_wall, judge_wall_in, zwidth, zwidth_sweep, WallVerdict, ZWidthRow, ZWidthSearch,
    ZWIDTH_CRITERION, ZWIDTH_RANGE_N_PER_M,
};

/// The paper's sub-regions of the force directions (Figs 10, 12), for the 3-wire device: where
/// the wires can make the contact force `f_e ∥ n` with non-negative tensions (A), where they
/// cannot but some wire still pulls along `n` (B), and where no wire has a component along `n`
/// (C: nothing can push the finger out; the paper's V = 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Region {
    /// All tensions non-negative: the force is made exactly.
    A,
    /// Some tension would be negative, but some wire pulls along `n`.
    B,
    /// No wire pulls along `n`.
    C,
}

impl Region {
    /// The outward normal of the wall the Z-width is judged on in this region, at the bench's
    /// start: A the wall facing the frame (`-z`), B a side wall (`+x`: the guide at `x = 0.37`
    /// still pulls along it), C the wall facing away from the frame (`+z`: no wire pulls along
    /// it, nothing can be rendered).
    pub fn wall_normal(self) -> Vec3 {
        match self {
            Region::A => Vec3::new(0.0, 0.0, -1.0),
            Region::B => Vec3::new(1.0, 0.0, 0.0),
            Region::C => Vec3::new(0.0, 0.0, 1.0),
        }
    }
}

/// The region of the force direction `n` at `position_m` for the configured guides.
pub fn region_of(config: &Config, position_m: Vec3, n: Vec3) -> Region {
    let g = &config.rig.guides_m;
    let cols: [Vec3; 3] = core::array::from_fn(|i| {
        let d = Vec3::new(g[i][0], g[i][1], 0.0) - position_m;
        d / d.norm()
    });
    if cols.iter().all(|u| u.dot(&n) <= 1e-9) {
        return Region::C;
    }
    let u = nalgebra::Matrix3::from_columns(&cols);
    match u.try_inverse() {
        Some(inv) if (inv * n).iter().all(|&t| t >= -1e-9) => Region::A,
        _ => Region::B,
    }
}

/// The bench's settings: how much of each sweep to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchPlan {
    /// Polar angles of the surface normals from the frame's axis (`-z`), degrees.
    pub polar_deg: &'static [f64],
    /// Azimuths of the tilted normals, degrees.
    pub azimuth_deg: &'static [f64],
    /// Wall damping values of the Z-width sweep, N·s/m.
    pub damping_n_s_per_m: &'static [f64],
    /// Bisection steps of the Z-width search.
    pub zwidth_steps: u32,
    /// Run the Z-width for every supported tension sensor (else the configured one only).
    pub all_sensors: bool,
    /// Run the Z-width at the bus's highest rate too (else at 1 kHz only).
    pub highest_rate: bool,
    /// Pushing forces of the pop-through sweep, newtons.
    pub push_n: &'static [f64],
    /// Stiffnesses the wall's feel is measured at, N/m (the configured one is added).
    pub feel_stiffness_n_per_m: &'static [f64],
}

impl BenchPlan {
    /// The full bench (a few minutes).
    pub const FULL: BenchPlan = BenchPlan {
        polar_deg: &[0.0, 15.0, 30.0, 45.0, 60.0, 90.0, 120.0, 150.0],
        azimuth_deg: &[0.0, 90.0, 180.0, 270.0],
        damping_n_s_per_m: &[0.0, 2.0, 5.0, 10.0],
        zwidth_steps: 7,
        all_sensors: true,
        highest_rate: true,
        push_n: &[1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0],
        feel_stiffness_n_per_m: &[800.0, 2000.0, 5000.0],
    };
    /// A few points of each sweep (seconds; tests).
    pub const QUICK: BenchPlan = BenchPlan {
        polar_deg: &[0.0, 45.0, 150.0],
        azimuth_deg: &[0.0],
        damping_n_s_per_m: &[5.0],
        zwidth_steps: 4,
        all_sensors: false,
        highest_rate: false,
        push_n: &[2.0, 6.0],
        feel_stiffness_n_per_m: &[],
    };
}

/// Stiffness rendered against a surface of normal `normal`.
#[derive(Debug, Clone, Serialize)]
pub struct StiffnessRow {
    /// Distribution algorithm.
    pub algorithm: String,
    /// Outward surface normal (the direction of the contact force).
    pub normal: [f64; 3],
    /// Angle of the normal from the frame's axis, degrees.
    pub polar_deg: f64,
    /// Azimuth of the normal, degrees.
    pub azimuth_deg: f64,
    /// The normal's region at the thimble's start.
    pub region: Region,
    /// Programmed stiffness K, N/m.
    pub programmed_n_per_m: f64,
    /// Rendered stiffness along the normal (secant between two pushes), N/m.
    pub rendered_n_per_m: f64,
    /// `rendered / programmed`.
    pub ratio: f64,
    /// Normal force and penetration at the two pushes (N, mm).
    pub pushes: [(f64, f64); 2],
    /// Both pushes settled (the thimble still within 0.2 mm over the window).
    pub settled: bool,
    /// Safety state at the end.
    pub safety: String,
    /// What the finger felt beyond what was asked over the run (`docs/felt-force.md`).
    pub felt: FeltTally,
}

/// Hand stiffness of the bench's operator in the stiffness sweep, N/m.
const STIFFNESS_HAND_N_PER_M: f64 = 400.0;
/// How far in front of the thimble every surface starts, metres.
const SURFACE_GAP_M: f64 = 0.003;

/// A plane `gap` in front of `start` (along `-n`) with outward normal `n`.
fn surface_ahead(start: Vec3, n: Vec3) -> Plane {
    Plane::new(start - n * SURFACE_GAP_M, n).expect("a unit normal")
}

/// The operator pushing along `-n`: the hand target moves to `depths_m[k]` past the surface
/// over 0.3 s from `times_s[k]` on, and holds there until the next move.
fn pusher(start: Vec3, n: Vec3, depths_m: &[f64], times_s: &[f64], k_hand: f64) -> VirtualOperator {
    let mut waypoints = vec![Waypoint {
        time_s: 0.0,
        target_m: start,
    }];
    let mut held = start;
    for (&d, &t) in depths_m.iter().zip(times_s) {
        waypoints.push(Waypoint {
            time_s: t,
            target_m: held,
        });
        held = start - n * (SURFACE_GAP_M + d);
        waypoints.push(Waypoint {
            time_s: t + 0.3,
            target_m: held,
        });
    }
    VirtualOperator::new(waypoints, k_hand, 4.0)
}

/// Mean normal force and penetration over `[from, to)`, and the spread of the penetration.
fn equilibrium(trace: &Trace, plane: &Plane, from_s: f64, to_s: f64) -> Equilibrium {
    let n = plane.normal();
    let (mut f, mut p, mut lo, mut hi, mut count) = (0.0, 0.0, f64::MAX, f64::MIN, 0.0);
    for s in trace.window(from_s, to_s) {
        let depth = -plane.signed_distance_m(&s.position_m);
        f += s.wire_force_n.dot(&n);
        p += depth;
        lo = lo.min(depth);
        hi = hi.max(depth);
        count += 1.0;
    }
    if count == 0.0 {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    (f / count, p / count, hi - lo)
}

/// The unit normal at `polar_deg` from `-z` and `azimuth_deg` around it.
fn normal_at(polar_deg: f64, azimuth_deg: f64) -> Vec3 {
    let (t, a) = (polar_deg.to_radians(), azimuth_deg.to_radians());
    Vec3::new(t.sin() * a.cos(), t.sin() * a.sin(), -t.cos())
}

/// Rendered vs programmed stiffness for P1 and P2 over the plan's normals.
pub fn stiffness_sweep(base: &Config, plan: &BenchPlan) -> Result<Vec<StiffnessRow>, String> {
    let start = start_position(base);
    let mut normals = Vec::new();
    for &polar in plan.polar_deg {
        if polar == 0.0 {
            normals.push((polar, 0.0));
        } else {
            normals.extend(plan.azimuth_deg.iter().map(|&a| (polar, a)));
        }
    }
    let mut rows = Vec::new();
    for algorithm in ["P1", "P2"] {
        for &(polar, azimuth) in &normals {
            let n = normal_at(polar, azimuth);
            let mut config = base.clone();
            config.control.algorithm = algorithm.into();
            let (rendered, a, b, final_safety, felt) = secant_stiffness(&config, n)?;
            let k = config.control.stiffness_n_per_m;
            rows.push(StiffnessRow {
                algorithm: algorithm.into(),
                normal: [n.x, n.y, n.z],
                polar_deg: polar,
                azimuth_deg: azimuth,
                region: region_of(&config, start, n),
                programmed_n_per_m: k,
                rendered_n_per_m: rendered,
                ratio: rendered / k,
                pushes: [(a.0, a.1 * 1e3), (b.0, b.1 * 1e3)],
                settled: a.2 < 2e-4 && b.2 < 2e-4,
                safety: safety_name(final_safety),
                felt,
            });
        }
    }
    Ok(rows)
}

/// Mean normal force, mean penetration and the penetration's spread over a window.
pub type Equilibrium = (f64, f64, f64);

/// The stiffness `config` renders along `n` (the secant between a 10 and a 25 mm push of a
/// 400 N/m hand, without a force field), with both equilibria, the safety state at the end and
/// the felt-force measure of the run.
pub fn secant_stiffness(
    config: &Config,
    n: Vec3,
) -> Result<(f64, Equilibrium, Equilibrium, SafetyState, FeltTally), String> {
    let start = start_position(config);
    let depths = [0.010, 0.025];
    let times = [0.0, 1.2];
    let windows = [(0.9, 1.2), (2.1, 2.4)];
    let mut config = config.clone();
    config.control.field_n = 0.0;
    let surface = surface_ahead(start, n);
    let trace = run(&Experiment {
        config,
        surface,
        operator: pusher(start, n, &depths, &times, STIFFNESS_HAND_N_PER_M),
        duration_s: 2.4,
        parts: Parts::Faithful,
    })?;
    let a = equilibrium(&trace, &surface, windows[0].0, windows[0].1);
    let b = equilibrium(&trace, &surface, windows[1].0, windows[1].1);
    Ok((
        (b.0 - a.0) / (b.1 - a.1),
        a,
        b,
        trace.final_safety,
        trace.felt,
    ))
}

fn safety_name(s: SafetyState) -> String {
    match s {
        SafetyState::Normal => "normal".into(),
        other => format!("{other:?}"),
    }
}

/// A tension sensor the bench runs the Z-width on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SensorSetup {
    /// `sensors.adc`.
    pub adc: TensionAdc,
    /// `sensors.sample_rate_sps` (0 for the drive's input).
    pub sample_rate_sps: u32,
    /// ADS1220 turbo mode.
    pub turbo: bool,
}

impl SensorSetup {
    /// The supported sensors at their fastest settings.
    pub const SUPPORTED: [SensorSetup; 4] = [
        SensorSetup {
            adc: TensionAdc::Ads1220,
            sample_rate_sps: 2000,
            turbo: true,
        },
        SensorSetup {
            adc: TensionAdc::Ads1220,
            sample_rate_sps: 330,
            turbo: false,
        },
        SensorSetup {
            adc: TensionAdc::Hx711,
            sample_rate_sps: 80,
            turbo: false,
        },
        SensorSetup {
            adc: TensionAdc::Drive,
            sample_rate_sps: 0,
            turbo: false,
        },
    ];

    /// The configured sensor.
    pub fn of(config: &Config) -> SensorSetup {
        let s = &config.sensors;
        SensorSetup {
            adc: s.adc,
            sample_rate_sps: if s.adc == TensionAdc::Drive {
                0
            } else {
                s.sample_rate_sps
            },
            turbo: s.ads1220_mode == Ads1220Mode::Turbo,
        }
    }

    /// `config` with this sensor (the loop degraded where the sensor needs it, and the staleness
    /// bound at least two conversion periods).
    pub fn apply(&self, config: &mut Config) {
        let s = &mut config.sensors;
        s.adc = self.adc;
        if self.sample_rate_sps > 0 {
            s.sample_rate_sps = self.sample_rate_sps;
            let two_periods_ms = (2000 / self.sample_rate_sps + 1) as u16;
            s.stale_after_ms = s.stale_after_ms.max(two_periods_ms);
        }
        s.ads1220_mode = if self.turbo {
            Ads1220Mode::Turbo
        } else {
            Ads1220Mode::Normal
        };
        config.control.allow_degraded_tension_loop = true;
    }

    /// A name for tables and plots.
    pub fn label(&self) -> String {
        match self.adc {
            TensionAdc::Drive => "drive input".into(),
            TensionAdc::Ads1220 if self.turbo => {
                format!("ADS1220 {} SPS turbo", self.sample_rate_sps)
            }
            TensionAdc::Ads1220 => format!("ADS1220 {} SPS", self.sample_rate_sps),
            TensionAdc::Hx711 => format!("HX711 {} SPS", self.sample_rate_sps),
        }
    }
}

/// How the wall is rendered, as far as the bench compares: the tension integral's speed gate
/// and the wires' stretch correction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rendering {
    /// `control.tension_integral_speed_gate_m_s` (0: the integral learns at any speed).
    pub integral_gate_m_s: f64,
    /// `control.stretch_compensation`.
    pub stretch_compensation: bool,
}

impl Rendering {
    /// The rendering before the gate and the stretch correction.
    pub const BEFORE: Rendering = Rendering {
        integral_gate_m_s: 0.0,
        stretch_compensation: false,
    };

    /// The configured rendering.
    pub fn of(control: &videt_config::ControlConfig) -> Rendering {
        Rendering {
            integral_gate_m_s: control.tension_integral_speed_gate_m_s,
            stretch_compensation: control.stretch_compensation,
        }
    }

    /// `config` rendering this way.
    pub fn apply(&self, config: &mut Config) {
        config.control.tension_integral_speed_gate_m_s = self.integral_gate_m_s;
        config.control.stretch_compensation = self.stretch_compensation;
    }

    /// A name for tables and plots.
    pub fn label(&self) -> String {
        let integral = if self.integral_gate_m_s > 0.0 {
            format!("integral < {:.0} mm/s", self.integral_gate_m_s * 1e3)
        } else {
            "integral at any speed".into()
        };
        let wires = if self.stretch_compensation {
            "stretch corrected"
        } else {
            "rigid wires"
        };
        format!("{integral}, {wires}")
    }
}

/// The renderings the bench compares: before the gate and the stretch correction, and the
/// configured one when it differs.
pub fn renderings_compared(base: &Config) -> Vec<Rendering> {
    let configured = Rendering::of(&base.control);
    if configured == Rendering::BEFORE {
        vec![configured]
    } else {
        vec![Rendering::BEFORE, configured]
    }
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

/// Penetration and held force at one pushing force.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PushRow {
    /// The hand's force at the end of the hold, N.
    pub push_n: f64,
    /// Normal force of the wires on the finger, N.
    pub wall_force_n: f64,
    /// Penetration, mm.
    pub penetration_mm: f64,
    /// Largest wire tension, N.
    pub max_tension_n: f64,
    /// Some wire is at its maximum tension: the wall gives way.
    pub saturated: bool,
    /// The penetration is deeper than the relief feature the bench asks about.
    pub popped_through: bool,
}

/// The pop-through sweep at the configured stiffness.
#[derive(Debug, Clone, Serialize)]
pub struct PopThroughReport {
    /// Wall stiffness, N/m.
    pub stiffness_n_per_m: f64,
    /// Depth of the relief feature the finger must not pass through, mm.
    pub feature_depth_mm: f64,
    /// The wearer's pushing force (the virtual operator's of the demo scene), N.
    pub wearer_push_n: f64,
    /// Penetration at the wearer's pushing force, mm (interpolated).
    pub wearer_penetration_mm: f64,
    /// Smallest pushing force tried that pops through the feature, N.
    pub pop_through_push_n: Option<f64>,
    /// Every push.
    pub pushes: Vec<PushRow>,
}

/// The demo operator's push: a 200 N/m hand 20 mm past the wall.
pub const WEARER_PUSH_N: f64 = 200.0 * 0.02;

/// Push on the wall facing the frame with each of `push_n` (a soft hand far past the wall:
/// nearly a constant force) and measure the penetration; `feature_mm`: the relief step the
/// finger must not pass.
pub fn pop_through(
    base: &Config,
    plan: &BenchPlan,
    feature_mm: f64,
) -> Result<PopThroughReport, String> {
    let mut config = base.clone();
    config.control.algorithm = "P2".into();
    let start = start_position(&config);
    let n = Vec3::new(0.0, 0.0, -1.0);
    let surface = surface_ahead(start, n);
    let k_hand = 100.0;
    let t_max = config.control.t_max_n;
    let mut pushes = Vec::new();
    for &push in plan.push_n {
        let trace = run(&Experiment {
            config: config.clone(),
            surface,
            operator: pusher(start, n, &[push / k_hand], &[0.0], k_hand),
            duration_s: 2.0,
            parts: Parts::Faithful,
        })?;
        let (force, depth, _) = equilibrium(&trace, &surface, 1.7, 2.0);
        let last = trace.samples.last().copied();
        let hand = last.map_or(f64::NAN, |s| -s.hand_force_n.dot(&n));
        let max_t = trace
            .window(1.7, 2.0)
            .map(|s| s.max_tension_n)
            .fold(0.0, f64::max);
        pushes.push(PushRow {
            push_n: hand,
            wall_force_n: force,
            penetration_mm: depth * 1e3,
            max_tension_n: max_t,
            saturated: max_t >= 0.98 * t_max,
            popped_through: depth * 1e3 > feature_mm,
        });
    }
    let wearer_penetration_mm = interpolate(
        &pushes
            .iter()
            .map(|p| (p.push_n, p.penetration_mm))
            .collect::<Vec<_>>(),
        WEARER_PUSH_N,
    );
    Ok(PopThroughReport {
        stiffness_n_per_m: config.control.stiffness_n_per_m,
        feature_depth_mm: feature_mm,
        wearer_push_n: WEARER_PUSH_N,
        wearer_penetration_mm,
        pop_through_push_n: pushes.iter().find(|p| p.popped_through).map(|p| p.push_n),
        pushes,
    })
}

/// Linear interpolation of `y(x)` through points sorted by `x` (clamped at the ends).
fn interpolate(points: &[(f64, f64)], x: f64) -> f64 {
    let Some(&(first_x, first_y)) = points.first() else {
        return f64::NAN;
    };
    if x <= first_x {
        return first_y;
    }
    for w in points.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if x <= x1 {
            return y0 + (y1 - y0) * (x - x0) / (x1 - x0);
        }
    }
    points[points.len() - 1].1
}

/// Everything the bench measured, with the configuration it ran on.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// The configuration file (or "defaults").
    pub config_origin: String,
    /// The configuration's control settings.
    pub control: videt_config::ControlConfig,
    /// The configuration's sensor settings.
    pub sensor: SensorSetup,
    /// The Z-width criterion.
    pub zwidth_criterion: String,
    /// Stiffness rows.
    pub stiffness: Vec<StiffnessRow>,
    /// Z-width rows.
    pub zwidth: Vec<ZWidthRow>,
    /// What the finger felt beyond what was asked over every stiffness and Z-width run.
    pub felt: FeltTally,
    /// The long hold and release the Z-width's stiffest walls also pass.
    pub hold_criterion: String,
    /// The wall's feel before and with the configured rendering.
    pub feel: Vec<FeelRow>,
    /// Pop-through.
    pub pop_through: PopThroughReport,
}

/// Run the whole bench.
pub fn run_bench(
    config: &Config,
    origin: &str,
    plan: &BenchPlan,
    feature_mm: f64,
) -> Result<BenchReport, String> {
    let stiffness = stiffness_sweep(config, plan)?;
    let zwidth = zwidth_sweep(config, plan)?;
    let mut felt = FeltTally::new();
    for row in &stiffness {
        felt.merge(&row.felt);
    }
    for verdict in zwidth.iter().flat_map(|row| &row.tried) {
        felt.merge(&verdict.felt);
    }
    Ok(BenchReport {
        config_origin: origin.into(),
        control: config.control.clone(),
        sensor: SensorSetup::of(config),
        zwidth_criterion: ZWIDTH_CRITERION.into(),
        stiffness,
        zwidth,
        felt,
        hold_criterion: wall_feel::HOLD_CRITERION.into(),
        feel: feel_sweep(config, plan)?,
        pop_through: pop_through(config, plan, feature_mm)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_frame_axis_is_region_a_and_its_opposite_region_c() {
        let config = Config::default();
        let start = start_position(&config);
        assert_eq!(region_of(&config, start, normal_at(0.0, 0.0)), Region::A);
        assert_eq!(region_of(&config, start, normal_at(180.0, 0.0)), Region::C);
    }

    #[test]
    fn interpolation_is_linear_and_clamped() {
        let p = [(1.0, 10.0), (3.0, 30.0)];
        assert_eq!(interpolate(&p, 2.0), 20.0);
        assert_eq!(interpolate(&p, 0.0), 10.0);
        assert_eq!(interpolate(&p, 9.0), 30.0);
    }
}
