//! Wire homing and auto-initialization of the base triangle (paper section 4.3), and the
//! workspace the measured rig can serve.
//!
//! **Homing.** At rest each wire is detached from the thimble and fully wound, its end pulled
//! against its guide ring. Winding a wire at a limited speed until its tension rises and its
//! encoder stops finds the count at which its free length is zero: that wire's encoder zero.
//!
//! **Auto-initialization.** With the three wires connected to the empty thimble, each wire in
//! turn is wound (speed-limited, tension-capped) while the other two pay out at low tension, until
//! the thimble stops against that wire's guide ring. The other two wire lengths are then two sides
//! of the base triangle, so three windings measure each side twice. A wound wire stopped with the
//! thimble at its ring has its end at the ring, exactly as when homed, so each winding also homes
//! its own wire: the procedure needs no encoder zero beforehand, and the lengths of every stop are
//! computed once the three zeros are known. The sides are combined by
//! least squares (for two equally weighted measurements of one side: their mean) and the
//! residuals reported; the guide points follow in the paper's frame (`x0` at the origin, `x1` on
//! the `+x` axis, `x2` in the `z = 0` plane with `y > 0`).
//!
//! [`Procedure`] is a per-period state machine: pure, allocation-free, time as an argument. Each
//! period it reads encoder counts, wire speeds, tensions and the fault inputs and writes a
//! set-point per wire: the force the motor applies to the wire (the runtime turns it into a
//! torque through the transmission, without tension feedback). A wire against its stop is a very
//! stiff load, and the empty thimble pinned at a ring makes the paying-out wires stiff too; a
//! force source is stable on such loads where a tension loop rings. The measured tensions serve
//! to detect the stops and the limits. Any failure ends it
//! with every set-point at the minimum tension and a [`Failure`] that says what went wrong.
//!
//! Lengths here are *free* (unstretched) lengths from the encoders. At the paying-out tension the
//! Kevlar stretches by `T·l/EA` (about 0.03 mm for 0.4 N over 0.5 m); this is left uncorrected.

use nalgebra::Matrix3;

use crate::kinematics::{Rig3, RigError};
use crate::Vec3;

use crate::WIREMAN_WIRES;

/// Settings of the procedure (from the configuration's `[autoinit]` and `[control]` sections).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProcedureParams {
    /// Metres of wire per encoder count.
    pub metres_per_count: f64,
    /// Tension of the wires that pay out, and the tension every wire is left at, N.
    pub pay_out_tension_n: f64,
    /// Largest tension set-point of a winding wire, N (it reaches it when the wire stops).
    pub wind_tension_max_n: f64,
    /// Target winding speed, m/s.
    pub wind_speed_m_s: f64,
    /// Speed loop: proportional gain, N per m/s of speed error.
    pub speed_kp_n_per_m_s: f64,
    /// Speed loop: integral gain, N per m of speed-error integral.
    pub speed_ki_n_per_m: f64,
    /// Time the set-points take to settle before winding starts, seconds.
    pub settle_s: f64,
    /// How long a wire must stay stopped with its tension up before the stop counts, seconds.
    pub stop_hold_s: f64,
    /// Averaging window of the lengths once stopped, seconds.
    pub measure_s: f64,
    /// Longest a homing or a winding may take, seconds.
    pub stage_timeout_s: f64,
    /// A winding wire shorter than this travel never moved: not connected, metres.
    pub min_travel_m: f64,
    /// Longest travel of one homing or winding before the wire counts as broken or slipping
    /// (its tension never rose), metres.
    pub max_wind_travel_m: f64,
    /// Shortest base-triangle side accepted, metres (a shorter paying-out wire is not connected).
    pub min_side_m: f64,
    /// Longest a wire may be (once its winding homed it) or pay out (before), metres.
    pub max_length_m: f64,
    /// Largest disagreement between the two measurements of one side, metres.
    pub side_tolerance_m: f64,
    /// Largest measured tension tolerated, N.
    pub max_tension_n: f64,
    /// How long a tension above `max_tension_n` is tolerated, seconds (filters spikes).
    pub over_tension_s: f64,
    /// Largest wire speed tolerated, m/s.
    pub max_speed_m_s: f64,
}

impl ProcedureParams {
    /// Tension above which a stopped winding wire counts as against its stop, N (well below
    /// the cap, so a transmission less efficient than configured still gets there).
    pub fn stop_tension_n(&self) -> f64 {
        self.pay_out_tension_n + 0.4 * (self.wind_tension_max_n - self.pay_out_tension_n)
    }
    /// Speed below which a wire counts as stopped, m/s.
    pub fn stop_speed_m_s(&self) -> f64 {
        0.05 * self.wind_speed_m_s
    }
}

/// What the procedure does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Plan {
    /// Home the selected (detached) wires, all at once; the others are held at the pay-out
    /// tension.
    Home {
        /// Which wires to home.
        wires: [bool; WIREMAN_WIRES],
    },
    /// Measure the base triangle with the wires connected to the thimble (each winding also
    /// homes its wire).
    Initialize,
}

/// Which limit was hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Limit {
    /// Measured tension above the limit, N.
    Tension {
        /// The tension measured, N.
        measured_n: f64,
    },
    /// Wire speed above the limit, m/s.
    Speed {
        /// The speed measured, m/s.
        measured_m_s: f64,
    },
    /// Wire longer than the limit (or, before its winding homed it, paid out beyond it).
    Length {
        /// The length, metres.
        measured_m: f64,
    },
}

/// One side of the base triangle: `(a, b)` with `a < b` names the side `d_ab`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Side(pub u8, pub u8);

/// Why the procedure failed. Each has its own message and stable name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Failure {
    /// The e-stop was pressed.
    EmergencyStop,
    /// A drive reported a fault or could not be read.
    DriveFault {
        /// The drive, when known.
        wire: Option<u8>,
    },
    /// A tension sensor failed.
    SensorFault,
    /// A safety limit was hit.
    LimitHit {
        /// The wire.
        wire: u8,
        /// Which limit, with the value measured.
        limit: Limit,
    },
    /// A stage took longer than allowed.
    Timeout {
        /// The wire being wound or homed (the first unfinished one).
        wire: u8,
        /// Seconds spent.
        elapsed_s: f64,
    },
    /// A wire never moved (wound: travel below the minimum; paying out: length below the
    /// shortest side): its end is not connected to the thimble.
    NotConnected {
        /// The wire.
        wire: u8,
        /// Its travel or length, metres.
        measured_m: f64,
    },
    /// A wire kept winding and its tension never rose: broken or slipping.
    TensionNeverRose {
        /// The wire.
        wire: u8,
        /// How far it wound, metres.
        travel_m: f64,
    },
    /// The two measurements of one side disagree beyond the tolerance.
    SidesDisagree {
        /// The side.
        side: Side,
        /// First measurement, metres.
        first_m: f64,
        /// Second measurement, metres.
        second_m: f64,
        /// The tolerance, metres.
        tolerance_m: f64,
    },
    /// The sides violate the triangle inequality.
    TriangleInequality {
        /// The sides `[d01, d02, d12]`, metres.
        sides_m: [f64; 3],
    },
    /// The triangle is degenerate (collinear or needle-thin guides).
    DegenerateTriangle {
        /// Its area, m².
        area_m2: f64,
    },
    /// Stopped from outside (an operator's stop, a signal).
    Cancelled,
}

impl Failure {
    /// A short, stable name for scripts and logs.
    pub const fn name(&self) -> &'static str {
        match self {
            Failure::EmergencyStop => "e-stop",
            Failure::DriveFault { .. } => "drive-fault",
            Failure::SensorFault => "sensor-fault",
            Failure::LimitHit { .. } => "limit-hit",
            Failure::Timeout { .. } => "timeout",
            Failure::NotConnected { .. } => "wire-not-connected",
            Failure::TensionNeverRose { .. } => "tension-never-rose",
            Failure::SidesDisagree { .. } => "sides-disagree",
            Failure::TriangleInequality { .. } => "triangle-inequality",
            Failure::DegenerateTriangle { .. } => "degenerate-triangle",
            Failure::Cancelled => "cancelled",
        }
    }
}

impl core::fmt::Display for Failure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Failure::EmergencyStop => f.write_str("the e-stop was pressed; release it and start again"),
            Failure::DriveFault { wire: Some(w) } => write!(f, "drive {w} reported a fault"),
            Failure::DriveFault { wire: None } => f.write_str("a drive failed or could not be read"),
            Failure::SensorFault => f.write_str("a wire-tension sensor failed"),
            Failure::LimitHit { wire, limit } => match limit {
                Limit::Tension { measured_n } => write!(
                    f,
                    "wire {wire}: tension limit hit ({measured_n:.2} N measured)"
                ),
                Limit::Speed { measured_m_s } => write!(
                    f,
                    "wire {wire}: speed limit hit ({:.0} mm/s measured)",
                    measured_m_s * 1e3
                ),
                Limit::Length { measured_m } => write!(
                    f,
                    "wire {wire}: length limit hit ({:.0} mm)",
                    measured_m * 1e3
                ),
            },
            Failure::Timeout { wire, elapsed_s } => write!(
                f,
                "wire {wire}: no stop reached within {elapsed_s:.1} s"
            ),
            Failure::NotConnected { wire, measured_m } => write!(
                f,
                "wire {wire} never moved ({:.1} mm): is its end connected to the thimble?",
                measured_m * 1e3
            ),
            Failure::TensionNeverRose { wire, travel_m } => write!(
                f,
                "wire {wire} wound {:.0} mm and its tension never rose: broken or slipping",
                travel_m * 1e3
            ),
            Failure::SidesDisagree {
                side,
                first_m,
                second_m,
                tolerance_m,
            } => write!(
                f,
                "side d{}{} measured twice disagrees: {:.2} mm vs {:.2} mm (tolerance {:.2} mm)",
                side.0,
                side.1,
                first_m * 1e3,
                second_m * 1e3,
                tolerance_m * 1e3
            ),
            Failure::TriangleInequality { sides_m } => write!(
                f,
                "measured sides d01 = {:.1} mm, d02 = {:.1} mm, d12 = {:.1} mm violate the triangle inequality",
                sides_m[0] * 1e3,
                sides_m[1] * 1e3,
                sides_m[2] * 1e3
            ),
            Failure::Cancelled => f.write_str("stopped before the end"),
            Failure::DegenerateTriangle { area_m2 } => write!(
                f,
                "the guide triangle is degenerate (area {:.1} cm²): guides collinear or too close",
                area_m2 * 1e4
            ),
        }
    }
}

/// The measured base triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BaseTriangle {
    /// Sides `[d01, d02, d12]`, metres (least-squares estimates).
    pub sides_m: [f64; 3],
    /// Residual of each measurement (measurement minus estimate), metres, in measurement order:
    /// winding 0 gives `d01, d02`; winding 1 gives `d01, d12`; winding 2 gives `d02, d12`.
    pub residuals_m: [f64; 6],
    /// The rig in the paper's frame.
    pub rig: Rig3,
}

/// The six side measurements of three windings: `lengths_at_stop_m[i][j]` is wire `j`'s length
/// when winding `i` stopped at ring `i`.
pub fn solve_base_triangle(
    lengths_at_stop_m: &[[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    side_tolerance_m: f64,
) -> Result<BaseTriangle, Failure> {
    let m = lengths_at_stop_m;
    // (side, first measurement, second measurement)
    let pairs = [
        (Side(0, 1), m[0][1], m[1][0]),
        (Side(0, 2), m[0][2], m[2][0]),
        (Side(1, 2), m[1][2], m[2][1]),
    ];
    let mut sides_m = [0.0; 3];
    for (k, (side, a, b)) in pairs.iter().enumerate() {
        if !(a.is_finite() && b.is_finite()) || (a - b).abs() > side_tolerance_m {
            return Err(Failure::SidesDisagree {
                side: *side,
                first_m: *a,
                second_m: *b,
                tolerance_m: side_tolerance_m,
            });
        }
        // Least squares of two equally weighted measurements of one unknown: the mean.
        sides_m[k] = 0.5 * (a + b);
    }
    let residuals_m = [
        m[0][1] - sides_m[0],
        m[0][2] - sides_m[1],
        m[1][0] - sides_m[0],
        m[1][2] - sides_m[2],
        m[2][0] - sides_m[1],
        m[2][1] - sides_m[2],
    ];
    let [d01, d02, d12] = sides_m;
    if d01 + d02 <= d12 || d01 + d12 <= d02 || d02 + d12 <= d01 {
        return Err(Failure::TriangleInequality { sides_m });
    }
    let rig = Rig3::from_sides(d01, d02, d12).map_err(|e| match e {
        RigError::Degenerate { area_m2 } => Failure::DegenerateTriangle {
            area_m2: heron_area_m2(sides_m).max(area_m2),
        },
        _ => Failure::DegenerateTriangle {
            area_m2: heron_area_m2(sides_m),
        },
    })?;
    Ok(BaseTriangle {
        sides_m,
        residuals_m,
        rig,
    })
}

/// Area of a triangle from its sides (Heron), m²; 0 when they do not close.
pub fn heron_area_m2(sides_m: [f64; 3]) -> f64 {
    let [a, b, c] = sides_m;
    let s = 0.5 * (a + b + c);
    let q = s * (s - a) * (s - b) * (s - c);
    if q > 0.0 {
        nalgebra::ComplexField::sqrt(q)
    } else {
        0.0
    }
}

/// What "the workspace the rig can serve" means: the points in front of the frame
/// (`z_min_m <= z <= z_max_m`, above the guide triangle's bounding box) where
///
/// 1. the wires can pull the thimble towards the frame (`-z`) with `force_n` while every tension
///    stays within `[t_min_n, t_max_n]` (the tensions `t = V⁻¹ f` of eq. 5 are `>= 0`, and
///    `t_min_n + max t <= t_max_n`), and
/// 2. the force map `V` of eq. 4 is well conditioned: `‖V‖_F · ‖V⁻¹‖_F <= max_condition`
///    (the Frobenius condition number, an upper bound of the 2-norm one), so a small length error
///    does not become a large force error.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorkspaceSpec {
    /// Force the wires must render towards the frame, N.
    pub force_n: f64,
    /// Minimum wire tension, N.
    pub t_min_n: f64,
    /// Maximum wire tension, N.
    pub t_max_n: f64,
    /// Largest Frobenius condition number of `V` accepted.
    pub max_condition: f64,
    /// Nearest plane of the workspace in front of the frame, metres.
    pub z_min_m: f64,
    /// Farthest plane, metres.
    pub z_max_m: f64,
    /// Grid step of the sampling, metres.
    pub step_m: f64,
}

/// The workspace of a rig, sampled on a grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Workspace {
    /// Volume of the served points, m³ (served grid cells times the cell volume).
    pub volume_m3: f64,
    /// Number of served grid points.
    pub points: u32,
    /// Lower corner of the served points' bounding box, metres.
    pub min_m: [f64; 3],
    /// Upper corner, metres.
    pub max_m: [f64; 3],
    /// The longest each wire gets anywhere in the workspace, metres: a wire must be usable at
    /// least this long.
    pub required_length_m: [f64; WIREMAN_WIRES],
}

/// Whether a point is served (see [`WorkspaceSpec`]).
pub fn serves_point(rig: &Rig3, spec: &WorkspaceSpec, p: &Vec3) -> bool {
    let v: Matrix3<f64> = rig.force_matrix(p);
    let Some(v_inv) = v.try_inverse() else {
        return false;
    };
    let condition = v.norm() * v_inv.norm();
    if !(condition.is_finite() && condition <= spec.max_condition) {
        return false;
    }
    let t = v_inv * Vec3::new(0.0, 0.0, -spec.force_n);
    t.iter()
        .all(|&ti| ti >= 0.0 && spec.t_min_n + ti <= spec.t_max_n)
}

/// Sample the workspace of `rig` (bounded loops: at most 200 steps per axis).
pub fn workspace(rig: &Rig3, spec: &WorkspaceSpec) -> Workspace {
    let g = rig.guides_m();
    let (mut lo, mut hi) = (g[0], g[0]);
    for gi in g.iter() {
        lo = lo.inf(gi);
        hi = hi.sup(gi);
    }
    let step = spec.step_m.max(1e-3);
    let count = |a: f64, b: f64| -> u32 {
        let n = nalgebra::ComplexField::floor((b - a) / step);
        if n.is_finite() && n >= 0.0 {
            (n as u32 + 1).min(200)
        } else {
            0
        }
    };
    let (nx, ny, nz) = (
        count(lo.x, hi.x),
        count(lo.y, hi.y),
        count(spec.z_min_m, spec.z_max_m),
    );
    let mut out = Workspace {
        volume_m3: 0.0,
        points: 0,
        min_m: [f64::INFINITY; 3],
        max_m: [f64::NEG_INFINITY; 3],
        required_length_m: [0.0; WIREMAN_WIRES],
    };
    for ix in 0..nx {
        for iy in 0..ny {
            for iz in 0..nz {
                let p = Vec3::new(
                    lo.x + ix as f64 * step,
                    lo.y + iy as f64 * step,
                    spec.z_min_m + iz as f64 * step,
                );
                if !serves_point(rig, spec, &p) {
                    continue;
                }
                out.points += 1;
                for k in 0..3 {
                    out.min_m[k] = out.min_m[k].min(p[k]);
                    out.max_m[k] = out.max_m[k].max(p[k]);
                }
                let l = rig.inverse(&p);
                for i in 0..WIREMAN_WIRES {
                    out.required_length_m[i] = out.required_length_m[i].max(l[i]);
                }
            }
        }
    }
    out.volume_m3 = out.points as f64 * step * step * step;
    if out.points == 0 {
        out.min_m = [0.0; 3];
        out.max_m = [0.0; 3];
    }
    out
}

/// What the procedure reads each period.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProcedureInput {
    /// Time, seconds (any origin; must not go backwards).
    pub time_s: f64,
    /// Encoder counts, positive = wound in.
    pub counts: [i64; WIREMAN_WIRES],
    /// Wire speeds, m/s, positive = winding.
    pub wind_speed_m_s: [f64; WIREMAN_WIRES],
    /// Measured tensions, N.
    pub tension_n: [f64; WIREMAN_WIRES],
    /// The e-stop is (latched) pressed.
    pub estop_pressed: bool,
    /// A drive failed (`Some(None)`: which one is unknown).
    pub drive_fault: Option<Option<u8>>,
    /// A tension sensor failed.
    pub sensor_fault: bool,
}

/// Where the procedure is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Every wire brought to the pay-out tension.
    Settle,
    /// Homing the selected wires.
    Homing,
    /// Winding this wire to its ring.
    Winding(u8),
    /// Finished successfully.
    Finished,
    /// Ended by a failure.
    Failed,
}

/// The procedure's verdict after a period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Status {
    /// Still running.
    Running,
    /// Finished: results are available.
    Finished,
    /// Failed: every set-point is at the pay-out (minimum) tension.
    Failed(Failure),
}

/// Per-wire stop detector and averaging window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct StopDetector {
    /// Time the wire was first seen stopped with its tension up.
    stopped_since_s: Option<f64>,
    /// Counts summed over the measuring window (relative to `base`, so no overflow).
    sum_counts: [f64; WIREMAN_WIRES],
    samples: u32,
    done: bool,
    base: [i64; WIREMAN_WIRES],
}

/// The homing / auto-initialization state machine. See the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Procedure {
    params: ProcedureParams,
    plan: Plan,
    stage: Stage,
    stage_start_s: f64,
    started: bool,
    detectors: [StopDetector; WIREMAN_WIRES],
    speed_integral_n: [f64; WIREMAN_WIRES],
    last_time_s: f64,
    start_counts: [i64; WIREMAN_WIRES],
    first_counts: [i64; WIREMAN_WIRES],
    counts_at_stop: [[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    zero_known: [bool; WIREMAN_WIRES],
    over_tension_s: [f64; WIREMAN_WIRES],
    home_counts: [i64; WIREMAN_WIRES],
    lengths_at_stop_m: [[f64; WIREMAN_WIRES]; WIREMAN_WIRES],
    result: Option<BaseTriangle>,
    failure: Option<Failure>,
    open_loop: [bool; WIREMAN_WIRES],
}

impl Procedure {
    /// A procedure that has not started; the first [`update`](Self::update) starts it.
    pub fn new(params: ProcedureParams, plan: Plan) -> Procedure {
        Procedure {
            params,
            plan,
            stage: Stage::Settle,
            stage_start_s: 0.0,
            started: false,
            detectors: [StopDetector::default(); WIREMAN_WIRES],
            speed_integral_n: [0.0; WIREMAN_WIRES],
            last_time_s: 0.0,
            start_counts: [0; WIREMAN_WIRES],
            first_counts: [0; WIREMAN_WIRES],
            counts_at_stop: [[0.0; WIREMAN_WIRES]; WIREMAN_WIRES],
            zero_known: [false; WIREMAN_WIRES],
            over_tension_s: [0.0; WIREMAN_WIRES],
            home_counts: [0; WIREMAN_WIRES],
            lengths_at_stop_m: [[0.0; WIREMAN_WIRES]; WIREMAN_WIRES],
            result: None,
            failure: None,
            open_loop: [false; WIREMAN_WIRES],
        }
    }

    /// Which wires the last period is winding under the procedure's own speed loop (their
    /// set-point may reach the winding cap); the others hold the pay-out tension.
    pub fn winding_wires(&self) -> [bool; WIREMAN_WIRES] {
        self.open_loop
    }

    /// The current stage.
    pub fn stage(&self) -> Stage {
        self.stage
    }

    /// The plan.
    pub fn plan(&self) -> Plan {
        self.plan
    }

    /// After a successful homing or initialization: the encoder count of each homed wire at
    /// free length zero (wires not homed: 0).
    pub fn homed_zero_counts(&self) -> [i64; WIREMAN_WIRES] {
        self.home_counts
    }

    /// After a successful initialization: the base triangle.
    pub fn result(&self) -> Option<&BaseTriangle> {
        self.result.as_ref()
    }

    /// The failure that ended the procedure, if any.
    pub fn failure(&self) -> Option<Failure> {
        self.failure
    }

    /// Lengths measured at each winding's stop (valid for the windings that finished).
    pub fn lengths_at_stop_m(&self) -> &[[f64; WIREMAN_WIRES]; WIREMAN_WIRES] {
        &self.lengths_at_stop_m
    }

    /// End the procedure from outside (e.g. an operator's stop), with every wire at the pay-out
    /// tension.
    pub fn abort(&mut self, failure: Failure, setpoint_n: &mut [f64; WIREMAN_WIRES]) {
        self.fail(failure, setpoint_n);
    }

    fn fail(&mut self, failure: Failure, setpoint_n: &mut [f64; WIREMAN_WIRES]) -> Status {
        if self.failure.is_none() && self.stage != Stage::Finished {
            self.failure = Some(failure);
            self.stage = Stage::Failed;
        }
        *setpoint_n = [self.params.pay_out_tension_n; WIREMAN_WIRES];
        self.open_loop = [false; WIREMAN_WIRES];
        match self.failure {
            Some(f) => Status::Failed(f),
            None => Status::Finished,
        }
    }

    /// Wire `wire`'s travel since the stage began, metres (positive = wound in).
    fn travel_m(&self, wire: usize, counts: i64) -> f64 {
        (counts - self.start_counts[wire]) as f64 * self.params.metres_per_count
    }

    fn enter(&mut self, stage: Stage, input: &ProcedureInput) {
        self.stage = stage;
        self.stage_start_s = input.time_s;
        self.start_counts = input.counts;
        self.detectors = [StopDetector::default(); WIREMAN_WIRES];
        self.speed_integral_n = [0.0; WIREMAN_WIRES];
    }

    /// Run one period: read `input`, write the tension set-points, say where the procedure is.
    /// Once finished or failed it keeps every set-point at the pay-out tension.
    pub fn update(
        &mut self,
        input: &ProcedureInput,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let status = self.step(input, setpoint_n);
        if status == Status::Running {
            self.govern(input, setpoint_n);
        }
        status
    }

    /// Speed governor of the tension-controlled wires: nothing holds an empty thimble, so wires
    /// at the pay-out tension could gather it (and themselves) fast. A wire winding faster than
    /// half the winding speed has its set-point lowered, to zero at the winding speed.
    fn govern(&self, input: &ProcedureInput, setpoint_n: &mut [f64; WIREMAN_WIRES]) {
        let v = self.params.wind_speed_m_s;
        for i in 0..WIREMAN_WIRES {
            if self.open_loop[i] {
                continue;
            }
            // (Only the wires holding the pay-out tension are governed.)
            let excess = (input.wind_speed_m_s[i] - 0.5 * v) / (0.5 * v);
            if excess > 0.0 {
                setpoint_n[i] *= (1.0 - excess).clamp(0.0, 1.0);
            }
        }
    }

    fn step(&mut self, input: &ProcedureInput, setpoint_n: &mut [f64; WIREMAN_WIRES]) -> Status {
        let p = self.params;
        self.open_loop = [false; WIREMAN_WIRES];
        match self.stage {
            Stage::Finished => {
                *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
                return Status::Finished;
            }
            Stage::Failed => return self.fail(Failure::SensorFault, setpoint_n),
            _ => {}
        }
        if !self.started {
            self.started = true;
            self.last_time_s = input.time_s;
            self.first_counts = input.counts;
            self.enter(Stage::Settle, input);
        }
        let dt = (input.time_s - self.last_time_s).max(0.0);
        self.last_time_s = input.time_s;

        // Faults and limits first: any of them ends the procedure.
        if input.estop_pressed {
            return self.fail(Failure::EmergencyStop, setpoint_n);
        }
        if let Some(wire) = input.drive_fault {
            return self.fail(Failure::DriveFault { wire }, setpoint_n);
        }
        if input.sensor_fault || input.tension_n.iter().any(|t| !t.is_finite()) {
            return self.fail(Failure::SensorFault, setpoint_n);
        }
        for i in 0..WIREMAN_WIRES {
            let wire = i as u8;
            if input.tension_n[i] > p.max_tension_n {
                self.over_tension_s[i] += dt;
                if self.over_tension_s[i] >= p.over_tension_s {
                    let limit = Limit::Tension {
                        measured_n: input.tension_n[i],
                    };
                    return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
                }
            } else {
                self.over_tension_s[i] = 0.0;
            }
            if input.wind_speed_m_s[i].abs() > p.max_speed_m_s {
                let limit = Limit::Speed {
                    measured_m_s: input.wind_speed_m_s[i],
                };
                return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
            }
            // A wire's length once its winding homed it; before, how far it paid out.
            let reference = if self.zero_known[i] {
                self.counts_at_stop[i][i]
            } else {
                self.first_counts[i] as f64
            };
            let paid_out = (reference - input.counts[i] as f64) * p.metres_per_count;
            if paid_out > p.max_length_m {
                let limit = Limit::Length {
                    measured_m: paid_out,
                };
                return self.fail(Failure::LimitHit { wire, limit }, setpoint_n);
            }
        }

        let elapsed = input.time_s - self.stage_start_s;
        match self.stage {
            Stage::Settle => {
                *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
                if elapsed >= p.settle_s {
                    let next = match self.plan {
                        Plan::Home { .. } => Stage::Homing,
                        Plan::Initialize => Stage::Winding(0),
                    };
                    self.enter(next, input);
                }
                Status::Running
            }
            Stage::Homing => self.homing(input, dt, elapsed, setpoint_n),
            Stage::Winding(w) => self.winding(w as usize, input, dt, elapsed, setpoint_n),
            Stage::Finished => Status::Finished,
            Stage::Failed => self.fail(Failure::SensorFault, setpoint_n),
        }
    }

    /// The speed-limited winding command of wire `i` (open-loop, see [`Self::open_loop`]): a
    /// PI loop on the winding speed whose output is a motor force between zero and the winding
    /// cap, so a stopped wire pulls with at most `wind_tension_max_n`.
    fn wind_setpoint(&mut self, i: usize, input: &ProcedureInput, dt: f64) -> f64 {
        let p = &self.params;
        self.open_loop[i] = true;
        let error = p.wind_speed_m_s - input.wind_speed_m_s[i];
        self.speed_integral_n[i] = (self.speed_integral_n[i] + p.speed_ki_n_per_m * error * dt)
            .clamp(0.0, p.wind_tension_max_n);
        (self.speed_integral_n[i] + p.speed_kp_n_per_m_s * error).clamp(0.0, p.wind_tension_max_n)
    }

    /// Feed wire `i`'s stop detector; true once the stop held and the window is averaged.
    fn detect_stop(&mut self, i: usize, input: &ProcedureInput) -> bool {
        let p = self.params;
        let stopped = input.tension_n[i] >= p.stop_tension_n()
            && input.wind_speed_m_s[i].abs() <= p.stop_speed_m_s();
        let d = &mut self.detectors[i];
        if d.done {
            return true;
        }
        match d.stopped_since_s {
            None if stopped => {
                d.stopped_since_s = Some(input.time_s);
            }
            None => {}
            Some(_) if !stopped => {
                // A stop that did not hold: start over.
                *d = StopDetector::default();
            }
            Some(since) => {
                let held = input.time_s - since;
                if held >= p.stop_hold_s {
                    if d.samples == 0 {
                        d.base = input.counts;
                    }
                    for j in 0..WIREMAN_WIRES {
                        d.sum_counts[j] += (input.counts[j] - d.base[j]) as f64;
                    }
                    d.samples += 1;
                    if held >= p.stop_hold_s + p.measure_s {
                        d.done = true;
                        return true;
                    }
                }
            }
        }
        false
    }

    /// Mean counts of wire `j` over wire `i`'s measuring window.
    fn mean_counts(&self, i: usize, j: usize) -> f64 {
        let d = &self.detectors[i];
        d.base[j] as f64 + d.sum_counts[j] / f64::from(d.samples.max(1))
    }

    fn homing(
        &mut self,
        input: &ProcedureInput,
        dt: f64,
        elapsed: f64,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let Plan::Home { wires } = self.plan else {
            return Status::Running;
        };
        let p = self.params;
        let mut all_done = true;
        for i in 0..WIREMAN_WIRES {
            if !wires[i] {
                setpoint_n[i] = p.pay_out_tension_n;
                continue;
            }
            let travel = self.travel_m(i, input.counts[i]);
            if self.detect_stop(i, input) {
                setpoint_n[i] = p.pay_out_tension_n;
                continue;
            }
            all_done = false;
            if travel > p.max_wind_travel_m {
                let wire = i as u8;
                return self.fail(
                    Failure::TensionNeverRose {
                        wire,
                        travel_m: travel,
                    },
                    setpoint_n,
                );
            }
            if elapsed > p.stage_timeout_s {
                return self.fail(
                    Failure::Timeout {
                        wire: i as u8,
                        elapsed_s: elapsed,
                    },
                    setpoint_n,
                );
            }
            setpoint_n[i] = self.wind_setpoint(i, input, dt);
        }
        if all_done {
            for i in 0..WIREMAN_WIRES {
                if wires[i] {
                    self.home_counts[i] = libm_round(self.mean_counts(i, i));
                }
            }
            self.stage = Stage::Finished;
            *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
            return Status::Finished;
        }
        Status::Running
    }

    fn winding(
        &mut self,
        w: usize,
        input: &ProcedureInput,
        dt: f64,
        elapsed: f64,
        setpoint_n: &mut [f64; WIREMAN_WIRES],
    ) -> Status {
        let p = self.params;
        *setpoint_n = [p.pay_out_tension_n; WIREMAN_WIRES];
        let wire = w as u8;
        let travel = self.travel_m(w, input.counts[w]);
        if travel > p.max_wind_travel_m {
            return self.fail(
                Failure::TensionNeverRose {
                    wire,
                    travel_m: travel,
                },
                setpoint_n,
            );
        }
        if !self.detect_stop(w, input) {
            if elapsed > p.stage_timeout_s {
                return self.fail(
                    Failure::Timeout {
                        wire,
                        elapsed_s: elapsed,
                    },
                    setpoint_n,
                );
            }
            setpoint_n[w] = self.wind_setpoint(w, input, dt);
            return Status::Running;
        }
        // Stopped with the thimble at ring `w`: wire `w` is homed, the other two give sides.
        for j in 0..WIREMAN_WIRES {
            self.counts_at_stop[w][j] = self.mean_counts(w, j);
        }
        self.zero_known[w] = true;
        let travel = (self.counts_at_stop[w][w] - self.start_counts[w] as f64) * p.metres_per_count;
        if travel < p.min_travel_m {
            return self.fail(
                Failure::NotConnected {
                    wire,
                    measured_m: travel,
                },
                setpoint_n,
            );
        }
        if w + 1 < WIREMAN_WIRES {
            self.enter(Stage::Winding(wire + 1), input);
            return Status::Running;
        }
        for i in 0..WIREMAN_WIRES {
            self.home_counts[i] = libm_round(self.counts_at_stop[i][i]);
            for j in 0..WIREMAN_WIRES {
                self.lengths_at_stop_m[i][j] =
                    (self.counts_at_stop[j][j] - self.counts_at_stop[i][j]) * p.metres_per_count;
            }
        }
        for i in 0..WIREMAN_WIRES {
            for j in 0..WIREMAN_WIRES {
                if i != j && self.lengths_at_stop_m[i][j] < p.min_side_m {
                    return self.fail(
                        Failure::NotConnected {
                            wire: j as u8,
                            measured_m: self.lengths_at_stop_m[i][j],
                        },
                        setpoint_n,
                    );
                }
            }
        }
        match solve_base_triangle(&self.lengths_at_stop_m, p.side_tolerance_m) {
            Ok(t) => {
                self.result = Some(t);
                self.stage = Stage::Finished;
                Status::Finished
            }
            Err(f) => self.fail(f, setpoint_n),
        }
    }
}

/// Round to the nearest integer count.
fn libm_round(x: f64) -> i64 {
    let r = nalgebra::ComplexField::floor(x + 0.5);
    r as i64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sides_of(g: &[Vec3; 3]) -> [f64; 3] {
        [
            (g[1] - g[0]).norm(),
            (g[2] - g[0]).norm(),
            (g[2] - g[1]).norm(),
        ]
    }

    fn exact_measurements(g: &[Vec3; 3]) -> [[f64; 3]; 3] {
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (g[j] - g[i]).norm();
            }
        }
        m
    }

    #[test]
    fn exact_measurements_reproduce_the_triangle_in_the_papers_frame() {
        let g = [
            Vec3::new(0.02, -0.01, 0.0),
            Vec3::new(0.41, 0.03, 0.0),
            Vec3::new(0.15, 0.33, 0.0),
        ];
        let t = solve_base_triangle(&exact_measurements(&g), 1e-3).unwrap();
        let truth = sides_of(&g);
        for k in 0..3 {
            assert!((t.sides_m[k] - truth[k]).abs() < 1e-12);
        }
        assert!(t.residuals_m.iter().all(|r| r.abs() < 1e-12));
        let h = t.rig.guides_m();
        assert_eq!(h[0], Vec3::zeros());
        assert_eq!(h[1].y, 0.0);
        assert!(h[2].y > 0.0);
        assert!((sides_of(h)[2] - truth[2]).abs() < 1e-12);
    }

    #[test]
    fn residuals_are_half_the_disagreement() {
        let g = [
            Vec3::zeros(),
            Vec3::new(0.37, 0.0, 0.0),
            Vec3::new(0.185, 0.30, 0.0),
        ];
        let mut m = exact_measurements(&g);
        m[0][1] += 0.4e-3;
        let t = solve_base_triangle(&m, 1e-3).unwrap();
        assert!((t.residuals_m[0] - 0.2e-3).abs() < 1e-12);
        assert!((t.residuals_m[2] + 0.2e-3).abs() < 1e-12);
        m[0][1] += 1.0e-3;
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::SidesDisagree {
                side: Side(0, 1),
                ..
            })
        ));
    }

    #[test]
    fn bad_triangles_have_their_own_errors() {
        // d01 + d02 < d12.
        let m = [[0.0, 0.2, 0.1], [0.2, 0.0, 0.5], [0.1, 0.5, 0.0]];
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::TriangleInequality { .. })
        ));
        // Nearly collinear: closes, but needle-thin.
        let m = [[0.0, 0.2, 0.2], [0.2, 0.0, 0.3999], [0.2, 0.3999, 0.0]];
        assert!(matches!(
            solve_base_triangle(&m, 1e-3),
            Err(Failure::DegenerateTriangle { .. })
        ));
    }

    #[test]
    fn workspace_of_the_papers_frame_is_in_front_of_the_triangle() {
        let rig = Rig3::from_sides(0.37, 0.35, 0.35).unwrap();
        let spec = WorkspaceSpec {
            force_n: 3.0,
            t_min_n: 0.3,
            t_max_n: 15.0,
            max_condition: 20.0,
            z_min_m: 0.1,
            z_max_m: 0.6,
            step_m: 0.02,
        };
        let ws = workspace(&rig, &spec);
        assert!(ws.points > 100, "{ws:?}");
        assert!(ws.min_m[2] >= 0.1 && ws.max_m[2] <= 0.6);
        // A point right in front of the centroid is served; one outside the triangle's prism is not.
        let c = (rig.guides_m()[0] + rig.guides_m()[1] + rig.guides_m()[2]) / 3.0;
        assert!(serves_point(&rig, &spec, &(c + Vec3::new(0.0, 0.0, 0.3))));
        assert!(!serves_point(&rig, &spec, &Vec3::new(-0.2, -0.2, 0.3)));
        for l in ws.required_length_m {
            assert!(l > 0.3 && l < 1.0, "{l}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::test_runner::Config { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(43), ..proptest::test_runner::Config::default() })]
        /// Any well-shaped triangle measured with errors below half the tolerance is accepted, its
        /// sides are within the measurement error, and the guides reproduce the sides.
        #[test]
        fn noisy_measurements_of_real_triangles_are_solved(
            x1 in 0.2f64..0.7, y1 in -0.1f64..0.1, x2 in -0.1f64..0.6, y2 in 0.15f64..0.5,
            noise in proptest::array::uniform6(-0.4e-3f64..0.4e-3),
        ) {
            let g = [Vec3::zeros(), Vec3::new(x1, y1, 0.0), Vec3::new(x2, y2, 0.0)];
            proptest::prop_assume!(Rig3::new(g).is_ok());
            let mut m = exact_measurements(&g);
            let slots = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
            for (k, (i, j)) in slots.iter().enumerate() {
                m[*i][*j] += noise[k];
            }
            let t = solve_base_triangle(&m, 1e-3).unwrap();
            let truth = sides_of(&g);
            for k in 0..3 {
                proptest::prop_assert!((t.sides_m[k] - truth[k]).abs() <= 0.4e-3 + 1e-12);
            }
            let solved = sides_of(t.rig.guides_m());
            for k in 0..3 {
                proptest::prop_assert!((solved[k] - t.sides_m[k]).abs() < 1e-9);
            }
            let r: f64 = t.residuals_m.iter().map(|r| r * r).sum();
            proptest::prop_assert!(r.sqrt() <= 1e-3);
        }

        /// Whatever the six numbers, the solver answers (a triangle or a failure) without panic.
        #[test]
        fn arbitrary_measurements_never_panic(m in proptest::array::uniform9(-1.0f64..2.0)) {
            let m = [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]];
            let _ = solve_base_triangle(&m, 2e-3);
        }
    }

    fn params() -> ProcedureParams {
        ProcedureParams {
            metres_per_count: 1e-5,
            pay_out_tension_n: 0.4,
            wind_tension_max_n: 3.0,
            wind_speed_m_s: 0.1,
            speed_kp_n_per_m_s: 20.0,
            speed_ki_n_per_m: 200.0,
            settle_s: 0.1,
            stop_hold_s: 0.1,
            measure_s: 0.1,
            stage_timeout_s: 10.0,
            min_travel_m: 0.02,
            max_wind_travel_m: 1.0,
            min_side_m: 0.05,
            max_length_m: 1.5,
            side_tolerance_m: 2e-3,
            max_tension_n: 15.0,
            over_tension_s: 0.005,
            max_speed_m_s: 0.5,
        }
    }

    /// A kinematic stand-in for a detached wire: it winds at the set speed while the set-point
    /// is above the pay-out tension, until its end reaches the ring at `stop_counts`.
    #[test]
    fn homing_finds_the_stop_count() {
        let p = params();
        let mut proc = Procedure::new(
            p,
            Plan::Home {
                wires: [true, false, true],
            },
        );
        let stop = [123_456_i64, 0, -98_765];
        let mut counts = [stop[0] - 20_000, 5, stop[2] - 3_000];
        let mut sp = [0.0; 3];
        let dt = 1e-3;
        let mut t = 0.0;
        let mut status = Status::Running;
        for _ in 0..20_000 {
            let mut input = ProcedureInput {
                time_s: t,
                counts,
                ..ProcedureInput::default()
            };
            for i in 0..3 {
                let at_stop = counts[i] >= stop[i];
                input.tension_n[i] = if at_stop { sp[i] } else { 0.4 };
                input.wind_speed_m_s[i] = if !at_stop && sp[i] > 0.45 { 0.1 } else { 0.0 };
            }
            status = proc.update(&input, &mut sp);
            if status != Status::Running {
                break;
            }
            for i in 0..3 {
                if input.wind_speed_m_s[i] > 0.0 {
                    counts[i] = (counts[i] + (0.1 * dt / p.metres_per_count) as i64).min(stop[i]);
                }
            }
            t += dt;
        }
        assert_eq!(status, Status::Finished);
        let z = proc.homed_zero_counts();
        assert_eq!(z[0], stop[0]);
        assert_eq!(z[2], stop[2]);
        assert_eq!(sp, [0.4; 3]);
    }

    #[test]
    fn estop_and_limits_end_at_the_pay_out_tension() {
        let mut proc = Procedure::new(params(), Plan::Initialize);
        let mut sp = [9.0; 3];
        let input = ProcedureInput {
            estop_pressed: true,
            tension_n: [0.4; 3],
            ..ProcedureInput::default()
        };
        assert_eq!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::EmergencyStop)
        );
        assert_eq!(sp, [0.4; 3]);
        let mut proc = Procedure::new(params(), Plan::Initialize);
        let mut input = ProcedureInput {
            tension_n: [0.4; 3],
            ..ProcedureInput::default()
        };
        input.wind_speed_m_s[1] = -0.9;
        assert!(matches!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::LimitHit {
                wire: 1,
                limit: Limit::Speed { .. }
            })
        ));
        // The failure stays latched.
        let input = ProcedureInput {
            tension_n: [0.4; 3],
            time_s: 1.0,
            ..ProcedureInput::default()
        };
        assert!(matches!(
            proc.update(&input, &mut sp),
            Status::Failed(Failure::LimitHit { .. })
        ));
    }
}
