//! Why the procedure fails: [`Failure`], with the [`Limit`] hit or the [`Side`] whose two
//! measurements disagree; each failure has its own message and stable name.

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
