//! A simulated AS5048A absolute magnetic encoder at protocol level: an embedded-hal
//! [`SpiDevice`] that answers 16-bit frames as the chip does, so the real angle driver
//! (`videt_drivers::angle`) runs end to end on the twin's geometry without hardware.
//!
//! What it models: the command frame `PAR | R/W | address`, the answer `PAR | EF | data` with
//! even parity, the answer to a command arriving in the next frame, the angle latched at the
//! end of the frame that asked for it, the sticky error flag and the error register (framing,
//! invalid command, command parity) cleared by reading it, and the DIAG/AGC and MAGNITUDE
//! registers. Writes (zero-position programming) are not modelled: they answer as an invalid
//! command. The encoder is mounted on its axis with a zero offset and a sense of rotation, so a
//! calibration has something to find.
//!
//! Faults ([`EncoderFaults`], shared with `Arc`, wait-free): a corrupted answer or command (one
//! frame each), the data line (MISO) stuck low or high, and a magnet too far away.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

use embedded_hal::spi::{self, Operation, SpiDevice};
use videt_control::polar_inverse;
use videt_hal::AngleAxis;

use crate::angle_sensors::{PositionSource, ENCODER_COUNTS_PER_TURN, ENCODER_RAD_PER_COUNT};

const PARITY_BIT: u16 = 1 << 15;
const FLAG_BIT: u16 = 1 << 14;
const DATA_MASK: u16 = 0x3FFF;

/// Error register bits.
const FRAMING: u16 = 0b001;
const COMMAND_INVALID: u16 = 0b010;
const COMMAND_PARITY: u16 = 0b100;

/// DIAG/AGC of a well-placed magnet: offset compensation finished, AGC 128.
pub const DIAG_HEALTHY: u16 = 0x0180;
/// DIAG/AGC of a magnet too far away: COMP high (weak field), AGC at its top.
pub const DIAG_FIELD_TOO_WEAK: u16 = 0x09FF;
/// MAGNITUDE of a well-placed magnet.
pub const MAGNITUDE_HEALTHY: u16 = 0x0F00;

fn with_parity(word: u16) -> u16 {
    let w = word & !PARITY_BIT;
    if w.count_ones() % 2 == 1 {
        w | PARITY_BIT
    } else {
        w
    }
}

/// How the encoder sits on its axis: the raw count at the axis' zero and whether counts run
/// against the angle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Mounting {
    /// Raw count at angle zero.
    pub zero_counts: u16,
    /// Counts decrease as the angle increases.
    pub reversed: bool,
}

impl Mounting {
    /// Zero at count 0, counts with the angle.
    pub const ALIGNED: Mounting = Mounting {
        zero_counts: 0,
        reversed: false,
    };

    /// The raw count the encoder reads at `angle_rad` (nearest count; 0 steps for a non-finite
    /// angle).
    pub fn raw_counts(&self, angle_rad: f64) -> u16 {
        let turn = i64::from(ENCODER_COUNTS_PER_TURN);
        let steps = if angle_rad.is_finite() {
            ((angle_rad / ENCODER_RAD_PER_COUNT).round() % turn as f64) as i64
        } else {
            0
        };
        let steps = if self.reversed { -steps } else { steps };
        (i64::from(self.zero_counts) + steps).rem_euclid(turn) as u16
    }
}

/// A fault of a simulated encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EncoderFault {
    /// The next answer arrives with one bit flipped (its parity fails).
    CorruptAnswer,
    /// The next command arrives with one bit flipped: the encoder raises its error flag.
    CorruptCommand,
    /// The data line reads low on every frame until restored (all zeros).
    MisoStuckLow,
    /// The data line reads high on every frame until restored (all ones).
    MisoStuckHigh,
    /// The magnet is too far away until restored (DIAG reports a weak field).
    WeakField,
}

/// Faults of one simulated encoder, posted from any thread (share with `Arc`).
#[derive(Debug, Default)]
pub struct EncoderFaults {
    corrupt_answer: AtomicU8,
    corrupt_command: AtomicU8,
    /// 0: healthy, 1: stuck low, 2: stuck high.
    miso: AtomicU8,
    weak_field: AtomicU8,
}

impl EncoderFaults {
    /// Make `fault` happen from the next frame on.
    pub fn inject(&self, fault: EncoderFault) {
        let (slot, value) = match fault {
            EncoderFault::CorruptAnswer => (&self.corrupt_answer, 1),
            EncoderFault::CorruptCommand => (&self.corrupt_command, 1),
            EncoderFault::MisoStuckLow => (&self.miso, 1),
            EncoderFault::MisoStuckHigh => (&self.miso, 2),
            EncoderFault::WeakField => (&self.weak_field, 1),
        };
        slot.store(value, Ordering::Release);
    }

    /// Clear every fault.
    pub fn restore(&self) {
        for slot in [
            &self.corrupt_answer,
            &self.corrupt_command,
            &self.miso,
            &self.weak_field,
        ] {
            slot.store(0, Ordering::Release);
        }
    }
}

/// A simulated AS5048A reading the angle `S` gives.
#[derive(Debug)]
pub struct SimAs5048a<S> {
    angle_rad: S,
    mounting: Mounting,
    /// What goes out in the next frame.
    answer: u16,
    error_register: u16,
    faults: Arc<EncoderFaults>,
}

impl<S: FnMut() -> f64> SimAs5048a<S> {
    /// An encoder on the axis whose angle `angle_rad` returns, mounted as `mounting`. Its first
    /// answer is all zeros, as after power-up.
    pub fn new(angle_rad: S, mounting: Mounting) -> Self {
        SimAs5048a {
            angle_rad,
            mounting,
            answer: 0,
            error_register: 0,
            faults: Arc::default(),
        }
    }

    /// The fault handle, to share with the thread that injects faults.
    pub fn faults(&self) -> Arc<EncoderFaults> {
        Arc::clone(&self.faults)
    }

    /// Take one frame's MOSI word (or a frame of the wrong length) and return its MISO word.
    fn frame(&mut self, mosi: Option<u16>) -> u16 {
        let mut out = self.answer;
        if self.faults.corrupt_answer.swap(0, Ordering::AcqRel) != 0 {
            out ^= 1;
        }
        out = match self.faults.miso.load(Ordering::Acquire) {
            1 => 0x0000,
            2 => 0xFFFF,
            _ => out,
        };
        let mosi = mosi.map(|w| {
            if self.faults.corrupt_command.swap(0, Ordering::AcqRel) != 0 {
                w ^ (1 << 3)
            } else {
                w
            }
        });
        let data = match mosi {
            None => {
                self.error_register |= FRAMING;
                0
            }
            Some(w) if w.count_ones() % 2 != 0 => {
                self.error_register |= COMMAND_PARITY;
                0
            }
            Some(w) if w & FLAG_BIT == 0 && w & DATA_MASK != 0 => {
                // A write: not modelled.
                self.error_register |= COMMAND_INVALID;
                0
            }
            Some(w) => match w & DATA_MASK {
                0x0000 => 0,
                0x0001 => core::mem::take(&mut self.error_register),
                0x3FFD if self.faults.weak_field.load(Ordering::Acquire) != 0 => {
                    DIAG_FIELD_TOO_WEAK
                }
                0x3FFD => DIAG_HEALTHY,
                0x3FFE => MAGNITUDE_HEALTHY,
                0x3FFF => self.mounting.raw_counts((self.angle_rad)()),
                _ => {
                    self.error_register |= COMMAND_INVALID;
                    0
                }
            },
        };
        let flag = if self.error_register != 0 {
            FLAG_BIT
        } else {
            0
        };
        self.answer = with_parity(flag | (data & DATA_MASK));
        out
    }
}

/// The simulated bus never fails; a malformed frame is the encoder's business (its error flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SimSpiError {}

impl spi::Error for SimSpiError {
    fn kind(&self) -> spi::ErrorKind {
        match *self {}
    }
}

impl<S: FnMut() -> f64> spi::ErrorType for SimAs5048a<S> {
    type Error = SimSpiError;
}

impl<S: FnMut() -> f64> SpiDevice for SimAs5048a<S> {
    /// One chip-select period: one 16-bit frame, MSB first. Any other number of bytes is a
    /// framing error. Allocation-free.
    fn transaction(&mut self, operations: &mut [Operation<'_, u8>]) -> Result<(), SimSpiError> {
        let total: usize = operations
            .iter()
            .map(|op| match op {
                Operation::Read(b) | Operation::TransferInPlace(b) => b.len(),
                Operation::Write(b) => b.len(),
                Operation::Transfer(r, w) => r.len().max(w.len()),
                Operation::DelayNs(_) => 0,
            })
            .sum();
        let mut mosi = [0u8; 2];
        let mut at = 0;
        for op in operations.iter() {
            let sent: &[u8] = match op {
                Operation::Write(b) => b,
                Operation::TransferInPlace(b) => b,
                Operation::Transfer(_, w) => w,
                // The host clocks zeros out while it only reads.
                Operation::Read(b) => {
                    at += b.len();
                    continue;
                }
                Operation::DelayNs(_) => continue,
            };
            for &byte in sent {
                if let Some(m) = mosi.get_mut(at) {
                    *m = byte;
                }
                at += 1;
            }
        }
        let miso = self
            .frame((total == 2).then_some(u16::from_be_bytes(mosi)))
            .to_be_bytes();
        let mut at = 0;
        for op in operations.iter_mut() {
            let received: &mut [u8] = match op {
                Operation::Read(b) | Operation::TransferInPlace(b) => b,
                Operation::Transfer(r, _) => r,
                Operation::Write(_) | Operation::DelayNs(_) => &mut [],
            };
            for byte in received.iter_mut() {
                *byte = miso.get(at).copied().unwrap_or(0);
                at += 1;
            }
        }
        Ok(())
    }
}

/// An encoder on `axis` of the one-wire device's wire guide, reading the angle of the thimble
/// position `source` gives (eq. 7 through [`polar_inverse`], as the HAL-level twin does),
/// mounted as `mounting`. For both axes, give each encoder a clone of an
/// [`Arc<SharedPosition>`](crate::SharedPosition).
pub fn encoder_on_axis<P: PositionSource>(
    mut source: P,
    axis: AngleAxis,
    mounting: Mounting,
) -> SimAs5048a<impl FnMut() -> f64> {
    SimAs5048a::new(
        move || {
            let c = polar_inverse(&source.thimble_position_m());
            match axis {
                AngleAxis::Azimuth => c.azimuth_rad,
                AngleAxis::Elevation => c.elevation_rad,
            }
        },
        mounting,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    fn xfer(enc: &mut SimAs5048a<impl FnMut() -> f64>, command: u16) -> u16 {
        let mut buf = command.to_be_bytes();
        enc.transfer_in_place(&mut buf).unwrap();
        u16::from_be_bytes(buf)
    }

    #[test]
    fn answers_arrive_one_frame_late_with_even_parity() {
        let mut enc = SimAs5048a::new(
            || FRAC_PI_2,
            Mounting {
                zero_counts: 100,
                reversed: true,
            },
        );
        assert_eq!(xfer(&mut enc, 0xFFFF), 0x0000);
        let a = xfer(&mut enc, 0x7FFD);
        // A quarter turn (4096 counts) against the counts from 100, wrapped.
        assert_eq!(a & DATA_MASK, 100 + 16384 - 4096);
        assert_eq!(a.count_ones() % 2, 0);
        assert_eq!(xfer(&mut enc, 0xC000), with_parity(DIAG_HEALTHY));
        assert_eq!(xfer(&mut enc, 0xFFFF), 0);
    }

    #[test]
    fn a_bad_frame_raises_the_flag_until_the_error_register_is_read() {
        let mut enc = SimAs5048a::new(|| 0.0, Mounting::ALIGNED);
        // Command parity wrong (0x7FFF has 15 ones).
        xfer(&mut enc, 0x7FFF);
        let a = xfer(&mut enc, 0xFFFF);
        assert_ne!(a & FLAG_BIT, 0);
        assert_ne!(xfer(&mut enc, 0x4001) & FLAG_BIT, 0);
        // The answer to the clear: the register, flag down.
        assert_eq!(xfer(&mut enc, 0xFFFF), with_parity(COMMAND_PARITY));
        assert_eq!(xfer(&mut enc, 0xFFFF), 0);
        // A frame of three bytes is a framing error.
        enc.write(&[0xFF, 0xFF, 0xFF]).unwrap();
        assert_ne!(xfer(&mut enc, 0x4001) & FLAG_BIT, 0);
        assert_eq!(xfer(&mut enc, 0xFFFF) & DATA_MASK, FRAMING);
    }

    #[test]
    fn injected_faults_show_on_the_line() {
        let mut enc = SimAs5048a::new(|| 0.0, Mounting::ALIGNED);
        let faults = enc.faults();
        xfer(&mut enc, 0xFFFF);
        faults.inject(EncoderFault::CorruptAnswer);
        assert_ne!(xfer(&mut enc, 0xFFFF).count_ones() % 2, 0);
        faults.inject(EncoderFault::MisoStuckHigh);
        assert_eq!(xfer(&mut enc, 0xFFFF), 0xFFFF);
        faults.inject(EncoderFault::MisoStuckLow);
        assert_eq!(xfer(&mut enc, 0xFFFF), 0x0000);
        faults.restore();
        faults.inject(EncoderFault::WeakField);
        xfer(&mut enc, 0x7FFD);
        assert_eq!(xfer(&mut enc, 0xFFFF), with_parity(DIAG_FIELD_TOO_WEAK));
    }
}
