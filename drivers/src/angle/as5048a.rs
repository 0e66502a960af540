//! ams AS5048A 14-bit absolute magnetic rotary encoder on SPI (mode 1, 16-bit frames, at most
//! 10 MHz; chip select high between frames).
//!
//! A command frame is `PAR | R/W | address[13:0]` (bit 15 even parity over the frame, bit 14
//! set for a read); an answer frame is `PAR | EF | data[13:0]`, EF being the error flag: the
//! sensor saw a bad frame from the host (framing, invalid command, parity). The answer to a
//! command comes in the frame after it, so reading the angle continuously pipelines: each frame
//! sends "read ANGLE" (`0xFFFF`) and receives the angle latched at the end of the previous one.
//!
//! Errors: an answer with bad parity is [`As5048aError::Parity`]; an answer with EF set is
//! [`As5048aError::ErrorFlag`], after the driver has cleared the flag by reading the error
//! register (its content goes into the error) and restarted the pipeline, so the next read
//! works again if the link does. Both cost at most two extra frames: every method is bounded.

use embedded_hal::spi::SpiDevice;

/// Register addresses.
pub mod reg {
    /// No operation.
    pub const NOP: u16 = 0x0000;
    /// Error register; reading it clears the error flag.
    pub const CLEAR_ERROR_FLAG: u16 = 0x0001;
    /// Diagnostics and automatic gain control.
    pub const DIAG_AGC: u16 = 0x3FFD;
    /// CORDIC magnitude.
    pub const MAGNITUDE: u16 = 0x3FFE;
    /// Angle, with the chip's own zero position applied (left at zero here: the host applies
    /// the calibration).
    pub const ANGLE: u16 = 0x3FFF;
}

/// Bit 15 of every frame: even parity over the whole frame.
const PARITY_BIT: u16 = 1 << 15;
/// Bit 14 of an answer: the error flag.
const ERROR_FLAG_BIT: u16 = 1 << 14;
/// Bit 14 of a command: read.
const READ_BIT: u16 = 1 << 14;
/// Data and address bits.
const DATA_MASK: u16 = 0x3FFF;

/// `word` with bit 15 set so that the frame has an even number of ones.
pub const fn with_parity(word: u16) -> u16 {
    let w = word & !PARITY_BIT;
    if w.count_ones() % 2 == 1 {
        w | PARITY_BIT
    } else {
        w
    }
}

/// Whether `frame` has even parity.
pub const fn parity_ok(frame: u16) -> bool {
    frame.count_ones().is_multiple_of(2)
}

/// The command frame reading register `address`.
pub const fn read_command(address: u16) -> u16 {
    with_parity(READ_BIT | (address & DATA_MASK))
}

/// "Read ANGLE" (`0xFFFF`).
pub const READ_ANGLE: u16 = read_command(reg::ANGLE);
/// "Read the error register", which clears the error flag (`0x4001`).
pub const CLEAR_ERROR_FLAG: u16 = read_command(reg::CLEAR_ERROR_FLAG);
/// "Read DIAG/AGC" (`0x7FFD`).
pub const READ_DIAG_AGC: u16 = read_command(reg::DIAG_AGC);
/// "Read MAGNITUDE" (`0x7FFE`).
pub const READ_MAGNITUDE: u16 = read_command(reg::MAGNITUDE);

/// The error register (0x0001): why the sensor raised its error flag.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ErrorRegister(pub u16);

impl ErrorRegister {
    /// Bit 0: a frame had the wrong number of clocks.
    pub const fn framing(self) -> bool {
        self.0 & 0b001 != 0
    }
    /// Bit 1: a command addressed no register or wrote a read-only one.
    pub const fn command_invalid(self) -> bool {
        self.0 & 0b010 != 0
    }
    /// Bit 2: a command frame had the wrong parity.
    pub const fn parity(self) -> bool {
        self.0 & 0b100 != 0
    }
}

impl core::fmt::Display for ErrorRegister {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let causes = [
            (self.framing(), "framing error"),
            (self.command_invalid(), "invalid command"),
            (self.parity(), "command parity error"),
        ];
        let mut first = true;
        for (_, text) in causes.iter().filter(|(set, _)| *set) {
            if !first {
                f.write_str(", ")?;
            }
            f.write_str(text)?;
            first = false;
        }
        if first {
            f.write_str("no cause recorded")?;
        }
        Ok(())
    }
}

/// The DIAG/AGC register (0x3FFD): the magnetic field as the sensor sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Diagnostics(pub u16);

impl Diagnostics {
    /// Automatic gain control, 0 (strong field) to 255 (weak field).
    pub const fn agc(self) -> u8 {
        (self.0 & 0xFF) as u8
    }
    /// Bit 8 (OCF): offset compensation finished; clear only briefly after power-up.
    pub const fn offset_compensation_finished(self) -> bool {
        self.0 & (1 << 8) != 0
    }
    /// Bit 9 (COF): CORDIC overflow; the angle and magnitude are invalid.
    pub const fn cordic_overflow(self) -> bool {
        self.0 & (1 << 9) != 0
    }
    /// Bit 10 (COMP low): the field is too strong (magnet too close).
    pub const fn field_too_strong(self) -> bool {
        self.0 & (1 << 10) != 0
    }
    /// Bit 11 (COMP high): the field is too weak (magnet missing, too far or off-axis).
    pub const fn field_too_weak(self) -> bool {
        self.0 & (1 << 11) != 0
    }

    /// The first thing wrong with the field, if anything, as an error.
    pub fn check<E>(self) -> Result<(), As5048aError<E>> {
        let agc = self.agc();
        if !self.offset_compensation_finished() {
            Err(As5048aError::NotReady {
                diagnostics: self.0,
            })
        } else if self.cordic_overflow() {
            Err(As5048aError::CordicOverflow { agc })
        } else if self.field_too_weak() {
            Err(As5048aError::FieldTooWeak { agc })
        } else if self.field_too_strong() {
            Err(As5048aError::FieldTooStrong { agc })
        } else {
            Ok(())
        }
    }
}

/// An AS5048A error.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum As5048aError<E> {
    /// The SPI bus failed.
    #[error("SPI bus error ({0:?})")]
    Bus(E),
    /// An answer failed its parity check: noise or a loose connection on the bus.
    #[error("parity error in the answer {word:#06x} (noise or a loose connection on the bus)")]
    Parity {
        /// The frame received.
        word: u16,
    },
    /// The sensor raised its error flag: it received a bad frame. The driver has cleared it.
    #[error("the sensor raised its error flag ({})", flag_cause(.register))]
    ErrorFlag {
        /// The error register read while clearing the flag (`None` when that answer was itself
        /// unusable).
        register: Option<ErrorRegister>,
    },
    /// Offset compensation has not finished: the sensor is still powering up, or nothing
    /// answers (a data line stuck low reads as all zeros).
    #[error("offset compensation not finished (DIAG/AGC {diagnostics:#06x}): the sensor is powering up or not answering")]
    NotReady {
        /// The DIAG/AGC register.
        diagnostics: u16,
    },
    /// CORDIC overflow: the angle is invalid.
    #[error("CORDIC overflow (AGC {agc}): the angle is invalid, magnetic field out of range")]
    CordicOverflow {
        /// Automatic gain control value.
        agc: u8,
    },
    /// The magnetic field is too weak.
    #[error("magnetic field too weak (AGC {agc}): magnet missing, too far or off-axis")]
    FieldTooWeak {
        /// Automatic gain control value.
        agc: u8,
    },
    /// The magnetic field is too strong.
    #[error("magnetic field too strong (AGC {agc}): magnet too close")]
    FieldTooStrong {
        /// Automatic gain control value.
        agc: u8,
    },
}

/// Text for the content of the error register, known or not.
fn flag_cause(register: &Option<ErrorRegister>) -> FlagCause {
    FlagCause(*register)
}

struct FlagCause(Option<ErrorRegister>);

impl core::fmt::Display for FlagCause {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(r) => write!(f, "{r}"),
            None => f.write_str("error register unreadable"),
        }
    }
}

impl<E> As5048aError<E> {
    /// The HAL error kind: a bus error or a corrupted answer means the link to the sensor is
    /// not reliable ([`Disconnected`](videt_hal::ErrorKind::Disconnected)); a field out of range
    /// is [`OutOfRange`](videt_hal::ErrorKind::OutOfRange); the sensor's own flags are
    /// [`Fault`](videt_hal::ErrorKind::Fault), or [`NotReady`](videt_hal::ErrorKind::NotReady)
    /// during its start-up.
    pub const fn kind(&self) -> videt_hal::ErrorKind {
        use videt_hal::ErrorKind;
        match self {
            As5048aError::Bus(_) | As5048aError::Parity { .. } => ErrorKind::Disconnected,
            As5048aError::ErrorFlag { .. } | As5048aError::CordicOverflow { .. } => {
                ErrorKind::Fault
            }
            As5048aError::NotReady { .. } => ErrorKind::NotReady,
            As5048aError::FieldTooWeak { .. } | As5048aError::FieldTooStrong { .. } => {
                ErrorKind::OutOfRange
            }
        }
    }
}

/// One AS5048A. Owns its SPI device; [`As5048a::release`] gives it back.
#[derive(Debug)]
pub struct As5048a<SPI> {
    spi: SPI,
    /// The last frame the sensor took was "read ANGLE": the next answer is an angle.
    primed: bool,
}

impl<SPI: SpiDevice> As5048a<SPI> {
    /// Clear an error flag left from before (power-up glitches on the lines), read the
    /// diagnostics and check that the sensor answers and sees its magnet in range, and leave
    /// the angle read pipelined. Three frames. **non-RT**.
    pub fn new(spi: SPI) -> Result<Self, As5048aError<SPI::Error>> {
        let mut sensor = As5048a::without_check(spi);
        // The answer is to whatever came before us: nothing to check in it.
        sensor.frame(CLEAR_ERROR_FLAG)?;
        sensor.diagnostics()?.check()?;
        Ok(sensor)
    }

    /// Take `spi` without a single frame: the first read starts the pipeline
    /// ([`read_angle_counts`](Self::read_angle_counts)).
    pub fn without_check(spi: SPI) -> Self {
        As5048a { spi, primed: false }
    }

    /// One 16-bit frame: send `command`, return the answer to the previous one.
    fn frame(&mut self, command: u16) -> Result<u16, As5048aError<SPI::Error>> {
        self.primed = false;
        let mut buf = command.to_be_bytes();
        self.spi
            .transfer_in_place(&mut buf)
            .map_err(As5048aError::Bus)?;
        self.primed = command == READ_ANGLE;
        Ok(u16::from_be_bytes(buf))
    }

    /// The 14 data bits of `answer` once its parity and error flag are checked; on the error
    /// flag, clear it first.
    fn accept(&mut self, answer: u16) -> Result<u16, As5048aError<SPI::Error>> {
        if !parity_ok(answer) {
            return Err(As5048aError::Parity { word: answer });
        }
        if answer & ERROR_FLAG_BIT != 0 {
            let register = self.clear_error_flag()?;
            return Err(As5048aError::ErrorFlag { register });
        }
        Ok(answer & DATA_MASK)
    }

    /// Read the error register, which clears the flag, and restart the angle pipeline. Two
    /// frames. The register's content, if its answer was sound.
    fn clear_error_flag(&mut self) -> Result<Option<ErrorRegister>, As5048aError<SPI::Error>> {
        self.frame(CLEAR_ERROR_FLAG)?;
        let answer = self.frame(READ_ANGLE)?;
        Ok((parity_ok(answer) && answer & ERROR_FLAG_BIT == 0)
            .then_some(ErrorRegister(answer & DATA_MASK)))
    }

    /// The raw angle, counts in `0..16384`, latched when the previous frame ended. **RT**: one
    /// frame; one more when the pipeline has to start (after a bus error or
    /// [`without_check`](Self::without_check)), two more to clear an error flag.
    pub fn read_angle_counts(&mut self) -> Result<u16, As5048aError<SPI::Error>> {
        if !self.primed {
            let answer = self.frame(READ_ANGLE)?;
            self.accept(answer)?;
        }
        let answer = self.frame(READ_ANGLE)?;
        self.accept(answer)
    }

    /// Read register `address` (two frames), leaving the angle read pipelined. The answer in
    /// the first frame is checked, so an error flag raised earlier is reported (and cleared)
    /// here. **RT**: bounded, at most four frames.
    pub fn read_register(&mut self, address: u16) -> Result<u16, As5048aError<SPI::Error>> {
        let answer = self.frame(read_command(address))?;
        self.accept(answer)?;
        let answer = self.frame(READ_ANGLE)?;
        self.accept(answer)
    }

    /// The DIAG/AGC register (two frames; see [`read_register`](Self::read_register)).
    pub fn diagnostics(&mut self) -> Result<Diagnostics, As5048aError<SPI::Error>> {
        self.read_register(reg::DIAG_AGC).map(Diagnostics)
    }

    /// The CORDIC magnitude, 14 bits (two frames; see [`read_register`](Self::read_register)).
    pub fn magnitude(&mut self) -> Result<u16, As5048aError<SPI::Error>> {
        self.read_register(reg::MAGNITUDE)
    }

    /// Give the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use embedded_hal_mock::eh1::spi::{Mock as SpiMock, Transaction as S};

    /// An answer frame carrying `data`, with the error flag if `flag`, and correct parity.
    pub(crate) fn answer(data: u16, flag: bool) -> u16 {
        with_parity((data & DATA_MASK) | if flag { ERROR_FLAG_BIT } else { 0 })
    }

    /// One frame on the mock: `command` out, `answer` in.
    pub(crate) fn frame(command: u16, answer: u16) -> [S<u8>; 3] {
        [
            S::transaction_start(),
            S::transfer_in_place(
                command.to_be_bytes().to_vec(),
                answer.to_be_bytes().to_vec(),
            ),
            S::transaction_end(),
        ]
    }

    /// A sound DIAG/AGC: offset compensation finished, AGC 0x50.
    pub(crate) const DIAG_OK: u16 = 0x0150;

    /// The frames of [`As5048a::new`] with a sound sensor.
    pub(crate) fn init_frames() -> Vec<S<u8>> {
        let mut t = Vec::new();
        t.extend(frame(CLEAR_ERROR_FLAG, 0x0000));
        t.extend(frame(READ_DIAG_AGC, answer(0, false)));
        t.extend(frame(READ_ANGLE, answer(DIAG_OK, false)));
        t
    }

    #[test]
    fn commands_carry_even_parity() {
        assert_eq!(READ_ANGLE, 0xFFFF);
        assert_eq!(CLEAR_ERROR_FLAG, 0x4001);
        assert_eq!(READ_DIAG_AGC, 0x7FFD);
        assert_eq!(READ_MAGNITUDE, 0x7FFE);
        assert_eq!(read_command(reg::NOP), 0xC000);
        for w in [READ_ANGLE, CLEAR_ERROR_FLAG, READ_DIAG_AGC, READ_MAGNITUDE] {
            assert!(parity_ok(w));
        }
        assert!(!parity_ok(0x0001));
        assert_eq!(answer(0x1234, false) & DATA_MASK, 0x1234);
        assert!(parity_ok(answer(0x1235, true)));
    }

    #[test]
    fn the_read_is_pipelined_one_frame_per_angle() {
        let mut t = init_frames();
        // Each frame asks for the angle and carries the one asked for by the frame before.
        t.extend(frame(READ_ANGLE, answer(100, false)));
        t.extend(frame(READ_ANGLE, answer(101, false)));
        t.extend(frame(READ_ANGLE, answer(16383, false)));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::new(spi.clone()).unwrap();
        assert_eq!(s.read_angle_counts(), Ok(100));
        assert_eq!(s.read_angle_counts(), Ok(101));
        assert_eq!(s.read_angle_counts(), Ok(16383));
        s.release();
        spi.done();
    }

    #[test]
    fn without_a_check_the_first_read_starts_the_pipeline() {
        let mut t = Vec::new();
        t.extend(frame(READ_ANGLE, 0x0000));
        t.extend(frame(READ_ANGLE, answer(4242, false)));
        t.extend(frame(READ_ANGLE, answer(4243, false)));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::without_check(spi.clone());
        assert_eq!(s.read_angle_counts(), Ok(4242));
        assert_eq!(s.read_angle_counts(), Ok(4243));
        s.release();
        spi.done();
    }

    #[test]
    fn a_parity_error_is_reported_and_the_pipeline_goes_on() {
        let mut t = init_frames();
        let corrupted = answer(2000, false) ^ 0x0004;
        t.extend(frame(READ_ANGLE, corrupted));
        t.extend(frame(READ_ANGLE, answer(2001, false)));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::new(spi.clone()).unwrap();
        assert_eq!(
            s.read_angle_counts(),
            Err(As5048aError::Parity { word: corrupted })
        );
        assert_eq!(s.read_angle_counts(), Ok(2001));
        s.release();
        spi.done();
    }

    #[test]
    fn an_error_flag_is_reported_with_its_cause_and_cleared() {
        let mut t = init_frames();
        t.extend(frame(READ_ANGLE, answer(0, true)));
        // Clearing: read the error register, then its content arrives with the next
        // "read ANGLE", which restarts the pipeline.
        t.extend(frame(CLEAR_ERROR_FLAG, answer(0, false)));
        t.extend(frame(READ_ANGLE, answer(0b100, false)));
        t.extend(frame(READ_ANGLE, answer(777, false)));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::new(spi.clone()).unwrap();
        let e = s.read_angle_counts().unwrap_err();
        assert_eq!(
            e,
            As5048aError::ErrorFlag {
                register: Some(ErrorRegister(0b100))
            }
        );
        assert_eq!(e.kind(), videt_hal::ErrorKind::Fault);
        assert_eq!(
            e.to_string(),
            "the sensor raised its error flag (command parity error)"
        );
        assert_eq!(s.read_angle_counts(), Ok(777));
        s.release();
        spi.done();
    }

    #[test]
    fn a_data_line_stuck_high_reads_as_an_error_flag_with_no_readable_cause() {
        let mut t = init_frames();
        // 0xFFFF: even parity, error flag set, on every frame.
        t.extend(frame(READ_ANGLE, 0xFFFF));
        t.extend(frame(CLEAR_ERROR_FLAG, 0xFFFF));
        t.extend(frame(READ_ANGLE, 0xFFFF));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::new(spi.clone()).unwrap();
        let e = s.read_angle_counts().unwrap_err();
        assert_eq!(e, As5048aError::ErrorFlag { register: None });
        assert!(e.to_string().contains("error register unreadable"), "{e}");
        s.release();
        spi.done();
    }

    #[test]
    fn set_up_refuses_a_sensor_that_does_not_see_its_magnet() {
        for (diag, expected) in [
            (0x0000, As5048aError::NotReady { diagnostics: 0 }),
            (0x03FF, As5048aError::CordicOverflow { agc: 0xFF }),
            (0x09FF, As5048aError::FieldTooWeak { agc: 0xFF }),
            (0x0500, As5048aError::FieldTooStrong { agc: 0 }),
        ] {
            let mut t = Vec::new();
            t.extend(frame(CLEAR_ERROR_FLAG, 0x0000));
            t.extend(frame(READ_DIAG_AGC, answer(0, false)));
            t.extend(frame(READ_ANGLE, answer(diag, false)));
            let mut spi = SpiMock::new(&t);
            let e = As5048a::new(spi.clone()).unwrap_err();
            assert_eq!(e, expected);
            spi.done();
        }
        assert_eq!(
            As5048aError::<()>::FieldTooWeak { agc: 255 }.kind(),
            videt_hal::ErrorKind::OutOfRange
        );
    }

    #[test]
    fn a_register_read_keeps_the_angle_pipelined() {
        let mut t = init_frames();
        t.extend(frame(READ_MAGNITUDE, answer(500, false)));
        t.extend(frame(READ_ANGLE, answer(0x0ABC, false)));
        t.extend(frame(READ_ANGLE, answer(501, false)));
        let mut spi = SpiMock::new(&t);
        let mut s = As5048a::new(spi.clone()).unwrap();
        assert_eq!(s.magnitude(), Ok(0x0ABC));
        assert_eq!(s.read_angle_counts(), Ok(501));
        s.release();
        spi.done();
    }

    /// An SPI device that refuses every transfer.
    pub(crate) struct DeadBus;

    impl embedded_hal::spi::ErrorType for DeadBus {
        type Error = embedded_hal::spi::ErrorKind;
    }

    impl SpiDevice for DeadBus {
        fn transaction(
            &mut self,
            _: &mut [embedded_hal::spi::Operation<'_, u8>],
        ) -> Result<(), Self::Error> {
            Err(embedded_hal::spi::ErrorKind::Other)
        }
    }

    #[test]
    fn a_bus_error_is_reported_as_a_lost_link() {
        let mut s = As5048a::without_check(DeadBus);
        let e = s.read_angle_counts().unwrap_err();
        assert_eq!(e, As5048aError::Bus(embedded_hal::spi::ErrorKind::Other));
        assert_eq!(e.kind(), videt_hal::ErrorKind::Disconnected);
        assert!(As5048a::new(DeadBus).is_err());
    }
}
