//! The wire drives: one brushless motor per wire, through a worm gear onto a pulley, with an
//! incremental encoder on the motor shaft.
//!
//! Sign conventions: a **positive motor torque winds the wire** (pulls the thimble towards the
//! guide ring); positive encoder counts mean the wire was wound in. The wire length is therefore
//! `length = length_at_zero - counts * metres_per_count`.

use crate::ErrorType;

/// Power state of a drive, as the CiA 402 state machine (or the twin) reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DriveState {
    /// Not powered; torque commands are ignored.
    #[default]
    Disabled,
    /// Powered, torque commands are followed.
    Enabled,
    /// Quick stop active: the drive brakes by itself.
    QuickStop,
    /// Fault latched; needs a fault reset.
    Fault,
}

/// One sample of a drive, taken at the start of a control cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DriveSample {
    /// Motor encoder position in quadrature counts (x4), positive = wire wound in.
    pub position_counts: i64,
    /// Motor velocity in counts per second, positive = winding.
    pub velocity_counts_per_s: f64,
    /// Power state.
    pub state: DriveState,
    /// Drive-specific error code (CiA 402 object 0x603F), 0 when none.
    pub error_code: u16,
}

/// The mechanical transmission from motor to wire: encoder, gear, pulley.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transmission {
    /// Encoder counts per motor revolution (a 500-line encoder read x4 gives 2000).
    pub counts_per_motor_rev: u32,
    /// Gear reduction, motor turns per pulley turn (25 for the 1:25 worm gear).
    pub gear_ratio: f64,
    /// Pulley radius on which the wire winds, metres.
    pub pulley_radius_m: f64,
    /// Gear efficiency in (0, 1], used to convert wire tension into motor torque.
    pub efficiency: f64,
}

impl Transmission {
    /// The paper's actuation module: 500-line encoder (x4), 1:25 worm gear, 20 mm pulley radius
    /// (0.0025 mm of wire per count; the paper quotes 0.01 mm per encoder pulse).
    pub const PAPER: Transmission = Transmission {
        counts_per_motor_rev: 2000,
        gear_ratio: 25.0,
        pulley_radius_m: 0.020,
        efficiency: 1.0,
    };

    /// Metres of wire wound in per encoder count.
    pub fn metres_per_count(&self) -> f64 {
        core::f64::consts::TAU * self.pulley_radius_m
            / (self.counts_per_motor_rev as f64 * self.gear_ratio)
    }

    /// Motor torque (N·m) that holds a wire tension (N) statically.
    pub fn torque_for_tension(&self, tension_n: f64) -> f64 {
        tension_n * self.pulley_radius_m / (self.gear_ratio * self.efficiency)
    }

    /// Wire tension (N) balanced by a motor torque (N·m) statically.
    pub fn tension_for_torque(&self, torque_nm: f64) -> f64 {
        torque_nm * self.gear_ratio * self.efficiency / self.pulley_radius_m
    }

    /// Wire speed (m/s, positive = winding) for a motor speed in counts per second.
    pub fn wire_speed(&self, velocity_counts_per_s: f64) -> f64 {
        velocity_counts_per_s * self.metres_per_count()
    }
}

/// The set of wire drives, read and written once per control cycle (all wires together, so a
/// bus implementation can exchange one SYNC-driven set of process data).
pub trait WireDrives<const N: usize>: ErrorType {
    /// Power the drives so torque commands are followed (**non-RT**: waits for the state machine).
    fn enable(&mut self) -> Result<(), Self::Error>;
    /// Remove power (**RT-safe**: sends the command and returns; the drive stops by itself).
    fn disable(&mut self) -> Result<(), Self::Error>;
    /// Latest sample of every drive. **RT**: never blocks longer than the bus exchange.
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), Self::Error>;
    /// Command motor torques in N·m, positive = winding. **RT**.
    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), Self::Error>;
}
