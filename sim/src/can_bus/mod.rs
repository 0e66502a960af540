//! A userspace CAN bus for the digital twin, so the real drive driver and simulated CiA 402
//! nodes exchange real CAN frames without hardware.
//!
//! Two transports share one frame type ([`SimFrame`]) and one fault model ([`BusFaults`]):
//! - [`InProcessBus`]: several endpoints in one process. Every frame an endpoint transmits is
//!   delivered to every *other* endpoint through a bounded, preallocated queue (a full queue drops
//!   the frame for that receiver and counts an overrun, as a CAN controller FIFO would). Ideal
//!   (at once) or timed ([`InProcessBus::timed`]): a bit rate, arbitration by identifier and
//!   frames queued while the bus is busy ([`wire`]), with the load measured ([`BusStats`]).
//! - [`udp`]: endpoints in separate processes, linked by a tiny hub over UDP on the loopback
//!   interface ([`udp::UdpHub`], [`udp::UdpEndpoint`]).
//! - [`socketcan`] (Linux): the nodes on a kernel CAN interface (`vcan0`, `can0`), so the
//!   driver under test goes through the kernel's CAN stack.
//!
//! Both implement `embedded_can::blocking::Can`, `embedded_can::nb::Can`, and a receive with a
//! timeout ([`SimFrame`]-returning `receive_timeout`).
//!
//! Fault injection ([`BusFaults`], changeable at run time): a frame drop rate, a delivery delay,
//! and bus-off (every transmit and receive fails with [`BusError::BusOff`]).

/// Implements `embedded-can`'s blocking and non-blocking `Can` for an endpoint that has
/// `send(&SimFrame)` and `receive_timeout(Duration) -> Option<SimFrame>`: the blocking receive
/// waits in 100 ms slices, the non-blocking one polls with a zero timeout.
macro_rules! impl_embedded_can {
    ($endpoint:ty) => {
        impl embedded_can::blocking::Can for $endpoint {
            type Frame = SimFrame;
            type Error = BusError;

            fn transmit(&mut self, frame: &SimFrame) -> Result<(), BusError> {
                self.send(frame)
            }

            fn receive(&mut self) -> Result<SimFrame, BusError> {
                loop {
                    if let Some(f) = self.receive_timeout(Duration::from_millis(100))? {
                        return Ok(f);
                    }
                }
            }
        }

        impl embedded_can::nb::Can for $endpoint {
            type Frame = SimFrame;
            type Error = BusError;

            fn transmit(&mut self, frame: &SimFrame) -> nb::Result<Option<SimFrame>, BusError> {
                self.send(frame).map(|()| None).map_err(nb::Error::Other)
            }

            fn receive(&mut self) -> nb::Result<SimFrame, BusError> {
                match self.receive_timeout(Duration::ZERO) {
                    Ok(Some(f)) => Ok(f),
                    Ok(None) => Err(nb::Error::WouldBlock),
                    Err(e) => Err(nb::Error::Other(e)),
                }
            }
        }
    };
}

mod faults;
mod frame;
mod in_process;
#[cfg(target_os = "linux")]
pub mod socketcan;
pub mod udp;
pub mod wire;

pub use faults::BusFaults;
pub use frame::SimFrame;
pub use in_process::{InProcessBus, InProcessEndpoint, TIMED_BUS_QUEUE};
pub use wire::{BusStats, BusStatsSnapshot};

/// An error of the userspace CAN bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusError {
    /// The bus is off (injected fault): nothing is sent or received.
    BusOff,
    /// Every other endpoint is gone.
    Disconnected,
    /// The bus is too busy: the transmit queue is full and the frame was not sent.
    TransmitQueueFull,
    /// A socket error of the cross-process transport (its `std::io::ErrorKind`).
    Io(std::io::ErrorKind),
}

impl core::fmt::Display for BusError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            BusError::BusOff => f.write_str("CAN bus off"),
            BusError::Disconnected => f.write_str("CAN bus disconnected (no other endpoint)"),
            BusError::TransmitQueueFull => {
                f.write_str("CAN transmit queue full (the bus cannot carry the traffic)")
            }
            BusError::Io(kind) => write!(f, "CAN bus socket error: {kind}"),
        }
    }
}

impl std::error::Error for BusError {}

impl embedded_can::Error for BusError {
    fn kind(&self) -> embedded_can::ErrorKind {
        // embedded-can has no bus-off kind; callers ask the endpoint's `is_bus_off`.
        embedded_can::ErrorKind::Other
    }
}
