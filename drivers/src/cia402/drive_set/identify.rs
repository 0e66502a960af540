//! What each drive is, read over SDO at start: its device type, identity and supported modes
//! (a drive that is not a CiA 402 one or lacks cyclic synchronous torque mode is refused), its
//! rated torque checked against the configuration, and the optional objects it lacks noted for
//! the startup report.

use canopen_rs::{Address, DataType, Value};

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::objects::means_absent;
use crate::cia402::error::DriveError;
use crate::cia402::identity::{DriveIdentity, StartupNote};

/// Bit of cyclic synchronous torque mode (10) in the supported drive modes (0x6502).
const CYCLIC_SYNCHRONOUS_TORQUE_BIT: u32 = 1 << 9;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// Remember that drive `i` lacks the optional object `index:subindex`.
    pub(super) fn note(&mut self, i: usize, index: u16, subindex: u8, code: u32) {
        self.gathering.notes.push(StartupNote {
            wire: i as u8,
            node: self.nodes[i].id,
            index,
            subindex,
            code,
        });
    }

    /// Read an optional `u32` object of drive `i`: `None` (and a note) when the drive lacks it.
    fn read_optional_u32(
        &mut self,
        i: usize,
        index: u16,
        subindex: u8,
    ) -> Result<Option<u32>, DriveError> {
        match self.sdo_read(i, Address::new(index, subindex), DataType::Unsigned32) {
            Ok(Value::Unsigned32(v)) => Ok(Some(v)),
            Ok(_) => Err(DriveError::SdoUnexpectedValue {
                wire: i as u8,
                node: self.nodes[i].id,
                index,
            }),
            Err(DriveError::SdoAbort { code, .. }) if means_absent(code) => {
                self.note(i, index, subindex, code);
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    /// Read drive `i`'s device type and identity; refuse a drive that is not a CiA 402 one or
    /// does not offer cyclic synchronous torque mode.
    pub(super) fn identify(&mut self, i: usize) -> Result<(), DriveError> {
        let (wire, node) = (i as u8, self.nodes[i].id);
        let device_type = match self.sdo_read(i, Address::new(0x1000, 0), DataType::Unsigned32)? {
            Value::Unsigned32(v) => v,
            _ => {
                return Err(DriveError::SdoUnexpectedValue {
                    wire,
                    node,
                    index: 0x1000,
                })
            }
        };
        let mut identity = DriveIdentity {
            device_type,
            ..DriveIdentity::default()
        };
        if !identity.is_cia402() {
            return Err(DriveError::NotCia402 {
                wire,
                node,
                device_type,
            });
        }
        identity.vendor_id = self.read_optional_u32(i, 0x1018, 1)?;
        identity.product_code = self.read_optional_u32(i, 0x1018, 2)?;
        identity.revision = self.read_optional_u32(i, 0x1018, 3)?;
        identity.serial = self.read_optional_u32(i, 0x1018, 4)?;
        self.gathering.drives.push((wire, node, identity));
        if let Some(modes) = self.read_optional_u32(i, 0x6502, 0)? {
            if modes & CYCLIC_SYNCHRONOUS_TORQUE_BIT == 0 {
                return Err(DriveError::NoCyclicTorque {
                    wire,
                    node,
                    supported_modes: modes,
                });
            }
        }
        Ok(())
    }

    /// Compare drive `i`'s rated torque (0x6076) with the configuration's; a drive without
    /// 0x6076 cannot be checked: the configuration rules.
    pub(super) fn check_rated_torque(&mut self, i: usize) -> Result<(), DriveError> {
        let unit = self.cfg.rated_torque_unit;
        let rated = unit.raw(self.cfg.rated_torque_nm);
        match self.read_optional_u32(i, 0x6076, 0)? {
            Some(v) if v != rated => Err(DriveError::RatedTorqueMismatch {
                wire: i as u8,
                node: self.nodes[i].id,
                drive_value: v,
                configured_value: rated,
                unit,
            }),
            _ => Ok(()),
        }
    }
}
