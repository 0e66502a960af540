//! The whole twin as the motors of simulated drive nodes, on the wall clock: the plant a
//! separate drive process (`videt sim-rig`) serves on a CAN interface, so a service in device
//! mode drives the twin's wires, thimble and virtual operator through the kernel's CAN stack.
//!
//! The physics catches up with the wall clock whenever a drive applies its torque (at each
//! SYNC), as a real rig moves between two bus exchanges. Each drive's analog input carries its
//! wire's strain-gauge reading (the twin's sensor model: offset, gain error, noise), scaled as
//! the load-cell amplifier of the configuration would scale it.
//!
//! On a machine too slow for the control loop's rate (an emulated CPU), the twin's world can
//! run in slow motion ([`RealTimeTwinPlant::with_time_scale`]): its time then advances a fixed
//! fraction of the wall clock's, so the loop's periods, as many as the machine manages, still
//! come as often per second of the twin's world as on the backpack, where a wall-clock world
//! would move three or four times as far between two periods as the loop is built for.

use std::time::Instant;

use videt_control::WireDevice;
use videt_hal::{DriveSample, Lifecycle, MonoTime, TensionSensors, WireDrives};

use crate::cia402_node::MotorPlant;
use crate::Twin;

/// How a tension reaches a drive's 16-bit analog input: `counts = zero + tension / scale`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnalogScale {
    /// Counts at zero tension.
    pub zero_counts: i32,
    /// Newtons per count.
    pub newtons_per_count: f64,
}

impl AnalogScale {
    /// The analog input value for `tension_n`, saturated to the 16-bit range.
    pub fn counts(&self, tension_n: f64) -> i16 {
        let c = f64::from(self.zero_counts) + tension_n / self.newtons_per_count;
        if c.is_nan() {
            return 0;
        }
        c.round().clamp(f64::from(i16::MIN), f64::from(i16::MAX)) as i16
    }
}

/// A [`Twin`] stepped on the wall clock behind simulated drives.
#[derive(Debug)]
pub struct RealTimeTwinPlant<const N: usize, D: WireDevice<N>> {
    twin: Twin<N, D>,
    origin: Instant,
    torque_nm: [f64; N],
    encoders: [DriveSample; N],
    analog: [i16; N],
    scale: [AnalogScale; N],
    sensor_failed: bool,
    time_scale: f64,
}

/// The most of the twin's time one call catches up.
const MAX_CATCH_UP_NS: u64 = 50_000_000;

impl<const N: usize, D: WireDevice<N>> RealTimeTwinPlant<N, D> {
    /// Take `twin` (its drives are enabled: the simulated nodes decide which torque is applied),
    /// its time following the wall clock from now on.
    pub fn new(mut twin: Twin<N, D>, scale: [AnalogScale; N]) -> RealTimeTwinPlant<N, D> {
        twin.set_clock_mode(crate::ClockMode::External);
        // The twin's own lifecycle stands for the motors' power stages, always on here.
        let _ = twin.configure();
        let _ = twin.activate();
        let _ = twin.enable();
        let mut plant = RealTimeTwinPlant {
            twin,
            origin: Instant::now(),
            torque_nm: [0.0; N],
            encoders: [DriveSample::default(); N],
            analog: [0; N],
            scale,
            sensor_failed: false,
            time_scale: 1.0,
        };
        plant.sample();
        plant
    }

    /// The twin's world in slow motion: `scale` seconds of its time per second of the wall
    /// clock, from now on (1: real time). Values outside (0, 1] are clamped into it.
    pub fn with_time_scale(mut self, scale: f64) -> RealTimeTwinPlant<N, D> {
        let scale = if scale.is_finite() {
            scale.clamp(1e-3, 1.0)
        } else {
            1.0
        };
        // The world's time so far is kept: only what follows runs slower.
        let world_ns = self.twin.sim_time().0 as f64;
        self.origin = Instant::now()
            .checked_sub(std::time::Duration::from_nanos((world_ns / scale) as u64))
            .unwrap_or(self.origin);
        self.time_scale = scale;
        self
    }

    /// Seconds of the twin's world per second of the wall clock.
    pub fn time_scale(&self) -> f64 {
        self.time_scale
    }

    /// The twin's time the wall clock stands for now.
    fn world_now(&self) -> MonoTime {
        MonoTime((self.origin.elapsed().as_nanos() as f64 * self.time_scale) as u64)
    }

    /// The twin.
    pub fn twin(&self) -> &Twin<N, D> {
        &self.twin
    }

    /// The twin, mutably (to inject faults).
    pub fn twin_mut(&mut self) -> &mut Twin<N, D> {
        &mut self.twin
    }

    /// Whether the last sensor reading failed (a disconnected strain gauge: the analog input
    /// then reads its zero).
    pub fn sensor_failed(&self) -> bool {
        self.sensor_failed
    }

    /// Apply every wire's motor torque at once: the physics is brought up to the wall clock
    /// once (under the torques held until now) and the encoders and strain gauges read once,
    /// where [`MotorPlant::apply_torque`] does that for each wire in turn.
    pub fn apply_torques(&mut self, torque_nm: &[f64; N]) {
        self.sample();
        self.torque_nm = *torque_nm;
        let _ = self.twin.write_torques(&self.torque_nm);
    }

    /// Bring the physics up to the wall clock and read the encoders and strain gauges.
    fn sample(&mut self) {
        // A process descheduled for long does not make the physics run a long burst of steps
        // at once: at most 50 ms of the twin's time are caught up per call.
        let now = self.world_now();
        let floor = MonoTime(now.0.saturating_sub(MAX_CATCH_UP_NS));
        if self.twin.sim_time() < floor {
            // The time beyond the catch-up is dropped: the world starts again from there.
            let behind_ns = (floor.0 - self.twin.sim_time().0) as f64 / self.time_scale;
            self.origin += std::time::Duration::from_nanos(behind_ns as u64);
        }
        self.twin.advance_to(self.world_now());
        let _ = self.twin.read_drives(&mut self.encoders);
        let mut tension = [0.0; N];
        self.sensor_failed = self.twin.read_tensions(&mut tension).is_err();
        for i in 0..N {
            self.analog[i] = if self.sensor_failed {
                self.scale[i].counts(0.0)
            } else {
                self.scale[i].counts(tension[i])
            };
        }
    }
}

impl<const N: usize, D: WireDevice<N>> MotorPlant for RealTimeTwinPlant<N, D> {
    fn apply_torque(&mut self, axis: usize, torque_nm: f64) {
        if axis >= N {
            return;
        }
        let mut torques = self.torque_nm;
        torques[axis] = torque_nm;
        self.apply_torques(&torques);
    }

    fn encoder(&self, axis: usize) -> (i64, f64) {
        self.encoders
            .get(axis)
            .map(|s| (s.position_counts, s.velocity_counts_per_s))
            .unwrap_or((0, 0.0))
    }

    fn analog_input(&self, axis: usize) -> i16 {
        self.analog.get(axis).copied().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_control::Rig3;

    const WIRES: usize = 3;
    use crate::{PlantParams, SensorModel, Vec3, VirtualOperator};

    fn twin() -> Twin<3, Rig3> {
        let params = PlantParams::paper_default();
        let g = *params.device.guides_m();
        let start = (g[0] + g[1] + g[2]) / 3.0 + Vec3::new(0.0, 0.0, 0.3);
        Twin::new(
            params,
            start,
            VirtualOperator::holding(start),
            SensorModel::ideal(),
        )
    }

    #[test]
    fn analog_counts_saturate_and_round() {
        let s = AnalogScale {
            zero_counts: 100,
            newtons_per_count: 0.01,
        };
        assert_eq!(s.counts(0.0), 100);
        assert_eq!(s.counts(1.0), 200);
        assert_eq!(s.counts(1e6), i16::MAX);
        assert_eq!(s.counts(-1e6), i16::MIN);
        assert_eq!(s.counts(f64::NAN), 0);
    }

    #[test]
    fn winding_torque_raises_the_analog_tension_and_winds_the_encoder() {
        let scale = AnalogScale {
            zero_counts: 0,
            newtons_per_count: 0.001,
        };
        let mut p = RealTimeTwinPlant::new(twin(), [scale; WIRES]);
        let (start_counts, _) = p.encoder(0);
        let torque = 0.004; // about 5 N on a 20 mm pulley behind a 1:25 gear
        let until = Instant::now() + std::time::Duration::from_millis(150);
        while Instant::now() < until {
            for axis in 0..WIRES {
                p.apply_torque(axis, torque);
            }
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let tension_n = f64::from(p.analog_input(0)) * scale.newtons_per_count;
        assert!(tension_n > 1.0, "tension {tension_n} N");
        assert!(p.twin().sim_time().0 > 100_000_000);
        assert_ne!(p.encoder(0).0, start_counts);
        assert!(!p.sensor_failed());
    }

    #[test]
    fn all_torques_at_once_drive_only_the_wires_they_name() {
        let scale = AnalogScale {
            zero_counts: 0,
            newtons_per_count: 0.001,
        };
        let mut p = RealTimeTwinPlant::new(twin(), [scale; WIRES]);
        let until = Instant::now() + std::time::Duration::from_millis(150);
        while Instant::now() < until {
            // Wire 1 wound, the others left slack.
            p.apply_torques(&[0.0, 0.004, 0.0]);
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        let tension_n = |axis| f64::from(p.analog_input(axis)) * scale.newtons_per_count;
        assert!(tension_n(1) > 1.0, "wire 1 at {} N", tension_n(1));
        assert!(
            tension_n(0) < 0.5 * tension_n(1) && tension_n(2) < 0.5 * tension_n(1),
            "tensions {:?}",
            [tension_n(0), tension_n(1), tension_n(2)]
        );
        assert!(p.twin().sim_time().0 > 100_000_000);
    }

    #[test]
    fn a_slowed_world_advances_its_fraction_of_the_wall_clock() {
        let scale = AnalogScale {
            zero_counts: 0,
            newtons_per_count: 0.001,
        };
        let started = Instant::now();
        let mut p = RealTimeTwinPlant::new(twin(), [scale; WIRES]).with_time_scale(0.25);
        assert_eq!(p.time_scale(), 0.25);
        for _ in 0..20 {
            std::thread::sleep(std::time::Duration::from_millis(10));
            p.apply_torques(&[0.004; WIRES]);
        }
        let wall_ns = started.elapsed().as_nanos() as f64;
        let world_ns = p.twin().sim_time().0 as f64;
        // At least a quarter of the 200 ms slept (each call catches up at most 50 ms of the
        // twin's time, more than a quarter of any sleep here), at most a quarter of the wall
        // clock's time since the start (and a step).
        assert!(
            world_ns >= 0.25 * 200e6 - 1e5,
            "{world_ns} ns after 200 ms of sleep"
        );
        assert!(
            world_ns <= 0.25 * wall_ns + 1e5,
            "{world_ns} ns in {wall_ns} ns"
        );
        assert_eq!(
            RealTimeTwinPlant::new(twin(), [scale; WIRES])
                .with_time_scale(f64::NAN)
                .time_scale(),
            1.0
        );
    }
}
