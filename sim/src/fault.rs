//! The faults a twin can suffer, scheduled by the twin itself or posted to its inbox.

/// A fault the twin can be scheduled to suffer (see [`Twin::schedule_fault`](crate::Twin::schedule_fault)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TwinFault {
    /// Wire N breaks.
    BreakWire(usize),
    /// The e-stop button is pressed (and stays pressed).
    PressEStop,
    /// Tension sensor N stops answering.
    FailTensionSensor(usize),
    /// Drive N latches a fault.
    FaultDrive(usize),
    /// Wire N's end comes off the thimble.
    DetachWire(usize),
    /// Wire N slips on its pulley by this many encoder counts (the pulley turns, the yarn
    /// does not).
    SlipWire(usize, i64),
}
