//! The recorded inputs of a period, read back by the control cycle as its devices.

use videt_hal::{
    AngleSensors, DriveSample, EStop, ErrorKind, ErrorType, TensionSensors, WireDrives,
};
use videt_runtime::cycle::{CycleInputs, EStopReading, TorqueWrite};

/// The recorded inputs of one period as the devices of [`ControlCycle::run`].
pub(super) struct RecordedDevices<'a> {
    pub(super) inputs: &'a CycleInputs,
}

impl ErrorType for RecordedDevices<'_> {
    type Error = ErrorKind;
}

impl<const N: usize> WireDrives<N> for RecordedDevices<'_> {
    fn enable(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
    fn disable(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
    fn read_drives(&mut self, out: &mut [DriveSample; N]) -> Result<(), ErrorKind> {
        out.copy_from_slice(&self.inputs.drives[..N]);
        if self.inputs.drives_read_ok {
            Ok(())
        } else {
            Err(ErrorKind::Fault)
        }
    }
    fn write_torques(&mut self, _torque_nm: &[f64; N]) -> Result<(), ErrorKind> {
        match self.inputs.torque_write {
            TorqueWrite::Failed => Err(ErrorKind::Fault),
            // A write the recorded cycle did not make succeeds here; the record then says
            // `Written` where the log says `NotWritten`, and the comparison reports it.
            TorqueWrite::Written | TorqueWrite::NotWritten => Ok(()),
        }
    }
}

impl<const N: usize> TensionSensors<N> for RecordedDevices<'_> {
    fn read_tensions(&mut self, out_n: &mut [f64; N]) -> Result<(), ErrorKind> {
        self.read_fresh_tensions(out_n).map(|_| ())
    }
    fn read_fresh_tensions(&mut self, out_n: &mut [f64; N]) -> Result<[bool; N], ErrorKind> {
        out_n.copy_from_slice(&self.inputs.tensions_read_n[..N]);
        if self.inputs.tensions_read_ok {
            let mut fresh = [false; N];
            fresh.copy_from_slice(&self.inputs.tensions_fresh[..N]);
            Ok(fresh)
        } else {
            Err(ErrorKind::Fault)
        }
    }
}

impl AngleSensors for RecordedDevices<'_> {
    fn read_angles(&mut self, out_rad: &mut [f64; 2]) -> Result<(), ErrorKind> {
        *out_rad = self.inputs.angles_rad;
        if self.inputs.angles_read_ok {
            Ok(())
        } else {
            Err(ErrorKind::Fault)
        }
    }
}

impl EStop for RecordedDevices<'_> {
    fn is_pressed(&mut self) -> Result<bool, ErrorKind> {
        match self.inputs.estop {
            EStopReading::Released => Ok(false),
            EStopReading::Pressed => Ok(true),
            EStopReading::Failed => Err(ErrorKind::Fault),
        }
    }
    fn reset(&mut self) -> Result<(), ErrorKind> {
        Ok(())
    }
}
