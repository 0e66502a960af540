//! The motors behind the simulated drives: the twin's, shared between threads
//! ([`SharedMotors`]), or a free rotor ([`FreeMotorPlant`]).

use super::*;

/// The motor(s) behind simulated drives: one axis per drive.
pub trait MotorPlant: Send {
    /// Apply a motor torque (N·m, positive = winding) on `axis` until the next call.
    fn apply_torque(&mut self, axis: usize, torque_nm: f64);
    /// Encoder position (counts, positive = wound in) and velocity (counts/s) of `axis`.
    fn encoder(&self, axis: usize) -> (i64, f64);
    /// The drive's analog input on `axis` (raw 16-bit signed value, e.g. a load-cell amplifier
    /// wired into the drive), sent in TPDO2 when the master maps it. Default: 0 (unwired).
    fn analog_input(&self, axis: usize) -> i16 {
        let _ = axis;
        0
    }
}

/// A shared plant: several node threads and the twin may hold it.
impl<P: MotorPlant> MotorPlant for Arc<Mutex<P>> {
    fn apply_torque(&mut self, axis: usize, torque_nm: f64) {
        if let Ok(mut p) = self.lock() {
            p.apply_torque(axis, torque_nm);
        }
    }
    fn encoder(&self, axis: usize) -> (i64, f64) {
        self.lock().map(|p| p.encoder(axis)).unwrap_or((0, 0.0))
    }
    fn analog_input(&self, axis: usize) -> i16 {
        self.lock().map(|p| p.analog_input(axis)).unwrap_or(0)
    }
}

/// A wait-free mailbox between simulated drives and a physics model that another thread
/// steps (the twin): the drives write torques and read encoders and analog inputs; the model's
/// owner reads the torques and publishes the encoders and analog inputs. Atomics only: neither
/// side ever blocks.
#[derive(Debug)]
pub struct SharedMotors {
    torque_bits: Vec<std::sync::atomic::AtomicU64>,
    counts: Vec<std::sync::atomic::AtomicI64>,
    speed_bits: Vec<std::sync::atomic::AtomicU64>,
    analog: Vec<std::sync::atomic::AtomicI16>,
}

impl SharedMotors {
    /// `axes` motors, zero torque, encoders and analog inputs at zero.
    pub fn new(axes: usize) -> SharedMotors {
        use std::sync::atomic::{AtomicI16, AtomicI64, AtomicU64};
        SharedMotors {
            torque_bits: (0..axes).map(|_| AtomicU64::new(0)).collect(),
            counts: (0..axes).map(|_| AtomicI64::new(0)).collect(),
            speed_bits: (0..axes).map(|_| AtomicU64::new(0)).collect(),
            analog: (0..axes).map(|_| AtomicI16::new(0)).collect(),
        }
    }

    /// Publish the analog input of the drive of `axis` (raw 16-bit value, e.g. the load-cell
    /// amplifier's output as the drive converts it).
    pub fn publish_analog_input(&self, axis: usize, value: i16) {
        self.analog[axis].store(value, Ordering::Release);
    }

    /// The torque the drive of `axis` applies now, N·m.
    pub fn torque_nm(&self, axis: usize) -> f64 {
        f64::from_bits(self.torque_bits[axis].load(Ordering::Acquire))
    }

    /// Publish the encoder of `axis` (counts, counts/s) as the physics computed it.
    pub fn publish_encoder(&self, axis: usize, counts: i64, counts_per_s: f64) {
        self.counts[axis].store(counts, Ordering::Release);
        self.speed_bits[axis].store(counts_per_s.to_bits(), Ordering::Release);
    }
}

impl MotorPlant for Arc<SharedMotors> {
    fn apply_torque(&mut self, axis: usize, torque_nm: f64) {
        self.torque_bits[axis].store(torque_nm.to_bits(), Ordering::Release);
    }
    fn encoder(&self, axis: usize) -> (i64, f64) {
        (
            self.counts[axis].load(Ordering::Acquire),
            f64::from_bits(self.speed_bits[axis].load(Ordering::Acquire)),
        )
    }
    fn analog_input(&self, axis: usize) -> i16 {
        self.analog[axis].load(Ordering::Acquire)
    }
}

/// A free motor per axis: rotor inertia and viscous friction, integrated on the wall clock
/// (for tests and demos without the twin's physics).
#[derive(Debug, Clone)]
pub struct FreeMotorPlant {
    /// Rotor inertia seen at the motor shaft, kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous friction, N·m per rad/s.
    pub damping_nm_s: f64,
    /// Encoder counts per motor revolution.
    pub counts_per_rev: f64,
    angle_rad: Vec<f64>,
    speed_rad_s: Vec<f64>,
    torque_nm: Vec<f64>,
    last: Vec<Option<Instant>>,
    analog: Vec<i16>,
}

impl FreeMotorPlant {
    /// `axes` motors at rest at angle zero.
    pub fn new(axes: usize, inertia_kg_m2: f64, damping_nm_s: f64, counts_per_rev: f64) -> Self {
        FreeMotorPlant {
            inertia_kg_m2,
            damping_nm_s,
            counts_per_rev,
            angle_rad: vec![0.0; axes],
            speed_rad_s: vec![0.0; axes],
            torque_nm: vec![0.0; axes],
            last: vec![None; axes],
            analog: vec![0; axes],
        }
    }

    /// Set the analog input the drive of `axis` reports from now on (raw 16-bit value).
    pub fn set_analog_input(&mut self, axis: usize, value: i16) {
        self.analog[axis] = value;
    }

    /// The torque last applied on `axis`.
    pub fn torque_nm(&self, axis: usize) -> f64 {
        self.torque_nm[axis]
    }

    fn advance(&mut self, axis: usize) {
        let now = Instant::now();
        if let Some(t) = self.last[axis] {
            let dt = (now - t).as_secs_f64().min(0.1);
            // Semi-implicit Euler with exact damping decay over the step.
            let acc = self.torque_nm[axis] / self.inertia_kg_m2;
            let decay = (-self.damping_nm_s / self.inertia_kg_m2 * dt).exp();
            self.speed_rad_s[axis] = self.speed_rad_s[axis] * decay + acc * dt;
            self.angle_rad[axis] += self.speed_rad_s[axis] * dt;
        }
        self.last[axis] = Some(now);
    }
}

impl MotorPlant for FreeMotorPlant {
    fn apply_torque(&mut self, axis: usize, torque_nm: f64) {
        self.advance(axis);
        self.torque_nm[axis] = torque_nm;
    }
    fn encoder(&self, axis: usize) -> (i64, f64) {
        let k = self.counts_per_rev / core::f64::consts::TAU;
        (
            (self.angle_rad[axis] * k).round() as i64,
            self.speed_rad_s[axis] * k,
        )
    }
    fn analog_input(&self, axis: usize) -> i16 {
        self.analog[axis]
    }
}
