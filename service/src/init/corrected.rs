//! A device whose tension readings are corrected by the strain gauges' two-point calibration
//! (`videt tension-calibrate`), when it has one: every other capability is passed through
//! unchanged. The service runs every device through it; without a calibration the readings
//! pass through too.

use videt_config::calibration::TensionCalibration;
use videt_hal::{
    Clock, DriveSample, EStop, ErrorType, Lifecycle, LifecycleState, MonoTime, TensionSensors,
    WireDrives,
};

/// `H` with corrected tension readings. Allocation-free; the correction is two flops per wire.
#[derive(Debug)]
pub struct CorrectedTensions<H> {
    inner: H,
    /// The calibration of each channel it has (`None`: the readings pass through).
    correction: Option<TensionCalibration>,
    /// Whether the correction is applied (left out while the commissioning check reads the
    /// sensors as configured).
    correcting: bool,
}

impl<H> CorrectedTensions<H> {
    /// Wrap `inner`, correcting its tension readings with `correction` (`None`: passing them
    /// through).
    pub fn new(inner: H, correction: Option<TensionCalibration>) -> Self {
        CorrectedTensions {
            inner,
            correction,
            correcting: true,
        }
    }
    /// Apply the correction (`true`, from the start) or pass the readings on raw.
    pub fn set_correcting(&mut self, correcting: bool) {
        self.correcting = correcting;
    }
    /// The wrapped device.
    pub fn inner(&self) -> &H {
        &self.inner
    }
    /// The wrapped device, mutably.
    pub fn inner_mut(&mut self) -> &mut H {
        &mut self.inner
    }
}

impl<H: ErrorType> ErrorType for CorrectedTensions<H> {
    type Error = H::Error;
}

impl<const N: usize, H: TensionSensors<N>> TensionSensors<N> for CorrectedTensions<H> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), Self::Error> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], Self::Error> {
        let fresh = self.inner.read_fresh_tensions(out_n)?;
        let Some(correction) = self.correction.as_ref().filter(|_| self.correcting) else {
            return Ok(fresh);
        };
        // (A calibration holds the WireMan's three channels.)
        for (i, t) in out_n.iter_mut().enumerate().take(correction.offset_n.len()) {
            *t = correction.correct(i, *t);
        }
        Ok(fresh)
    }
}

impl<const N: usize, H: WireDrives<N>> WireDrives<N> for CorrectedTensions<H> {
    fn enable(&mut self) -> Result<(), Self::Error> {
        self.inner.enable()
    }
    fn disable(&mut self) -> Result<(), Self::Error> {
        self.inner.disable()
    }
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), Self::Error> {
        self.inner.read_drives(out)
    }
    fn write_torques(&mut self, torque_nm: &[f64; N]) -> Result<(), Self::Error> {
        self.inner.write_torques(torque_nm)
    }
}

impl<H: Lifecycle> Lifecycle for CorrectedTensions<H> {
    fn configure(&mut self) -> Result<(), Self::Error> {
        self.inner.configure()
    }
    fn activate(&mut self) -> Result<(), Self::Error> {
        self.inner.activate()
    }
    fn deactivate(&mut self) -> Result<(), Self::Error> {
        self.inner.deactivate()
    }
    fn lifecycle_state(&self) -> LifecycleState {
        self.inner.lifecycle_state()
    }
}

impl<H: videt_hal::AngleSensors> videt_hal::AngleSensors for CorrectedTensions<H> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), Self::Error> {
        self.inner_mut().read_angles(out_rad)
    }
}

impl<H: EStop> EStop for CorrectedTensions<H> {
    fn is_pressed(&mut self) -> Result<bool, Self::Error> {
        self.inner.is_pressed()
    }
    fn reset(&mut self) -> Result<(), Self::Error> {
        self.inner.reset()
    }
}

impl<H: Clock> Clock for CorrectedTensions<H> {
    fn now(&self) -> MonoTime {
        self.inner.now()
    }
    fn sleep_until(&mut self, deadline: MonoTime) {
        self.inner.sleep_until(deadline)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use videt_assembly::WiremanTwin as Twin;
    use videt_runtime::WIREMAN_WIRES;
    use videt_sim::{PlantParams, SensorModel, Vec3, VirtualOperator};

    #[test]
    fn readings_are_corrected_by_offset_and_gain() {
        let p = Vec3::new(0.18, 0.12, 0.3);
        let sensors = SensorModel {
            noise_std_n: 0.0,
            ..SensorModel::default()
        };
        let mut raw = Twin::new(
            PlantParams::paper_default(),
            p,
            VirtualOperator::holding(p),
            sensors.clone(),
        );
        let mut c = TensionCalibration::default();
        for i in 0..WIREMAN_WIRES {
            c.offset_n[i] = sensors.offset_n[i];
            c.gain[i] = 1.0 / (1.0 + sensors.gain_error[i]);
        }
        let twin = Twin::new(
            PlantParams::paper_default(),
            p,
            VirtualOperator::holding(p),
            sensors,
        );
        let mut corrected = CorrectedTensions::new(twin, Some(c));
        let (mut a, mut b) = ([0.0; WIREMAN_WIRES], [0.0; WIREMAN_WIRES]);
        raw.read_tensions(&mut a).unwrap();
        corrected.read_tensions(&mut b).unwrap();
        for i in 0..WIREMAN_WIRES {
            // The plant is at rest with zero tension: the raw reading is the offset alone.
            assert!((a[i] - raw_offset(i)).abs() < 1e-12);
            assert!(b[i].abs() < 1e-12, "wire {i}: {}", b[i]);
        }
        // Left out, the readings are the sensors' own; back in, corrected again.
        corrected.set_correcting(false);
        corrected.read_tensions(&mut b).unwrap();
        for i in 0..WIREMAN_WIRES {
            assert!((b[i] - raw_offset(i)).abs() < 1e-12, "wire {i}: {}", b[i]);
        }
        corrected.set_correcting(true);
        corrected.read_tensions(&mut b).unwrap();
        assert!(b.iter().all(|t| t.abs() < 1e-12), "{b:?}");
    }

    fn raw_offset(i: usize) -> f64 {
        SensorModel::<WIREMAN_WIRES>::default().offset_n[i]
    }
}
