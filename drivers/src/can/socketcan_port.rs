//! SocketCAN backend (Linux): a raw CAN socket with error frames enabled, so bus-off is seen.
//! The `socketcan` crate talks to the kernel directly and needs no system library.

use core::time::Duration;

use embedded_can::blocking::Can;
use socketcan::{CanFrame, CanSocket, Socket, SocketOptions};

use super::CanPort;

/// A SocketCAN interface (`can0`, `vcan0`, ...) as a [`CanPort`].
#[derive(Debug)]
pub struct SocketCanPort {
    socket: CanSocket,
    bus_off: bool,
}

impl SocketCanPort {
    /// Open interface `ifname`, receiving error frames (to detect bus-off). **non-RT**.
    pub fn open(ifname: &str) -> std::io::Result<SocketCanPort> {
        let socket = CanSocket::open(ifname)?;
        socket.set_error_filter_accept_all()?;
        Ok(SocketCanPort {
            socket,
            bus_off: false,
        })
    }

    /// Give the socket back.
    pub fn release(self) -> CanSocket {
        self.socket
    }

    fn note(&mut self, e: &socketcan::Error) {
        if let socketcan::Error::Can(can) = e {
            if can
                .into_iter()
                .any(|c| matches!(c, socketcan::errors::ErrorCause::BusOff))
            {
                self.bus_off = true;
            }
        }
    }
}

impl Can for SocketCanPort {
    type Frame = CanFrame;
    type Error = socketcan::Error;

    fn transmit(&mut self, frame: &CanFrame) -> Result<(), socketcan::Error> {
        let r = self.socket.transmit(frame);
        match &r {
            Ok(()) => self.bus_off = false,
            Err(e) => self.note(e),
        }
        r
    }

    fn receive(&mut self) -> Result<CanFrame, socketcan::Error> {
        let r = self.socket.receive();
        if let Err(e) = &r {
            self.note(e);
        }
        r
    }
}

impl CanPort for SocketCanPort {
    fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, socketcan::Error> {
        match self.socket.read_frame_timeout(timeout) {
            Ok(CanFrame::Error(frame)) => {
                let e = socketcan::Error::from(frame.into_error());
                self.note(&e);
                Err(e)
            }
            Ok(frame) => Ok(Some(frame)),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(socketcan::Error::from(e)),
        }
    }

    fn is_bus_off(&self) -> bool {
        self.bus_off
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[ignore = "needs a vcan0 interface (ip link add dev vcan0 type vcan && ip link set up vcan0)"]
    fn opens_vcan_and_times_out_without_traffic() {
        let mut p = SocketCanPort::open("vcan0").unwrap();
        assert!(p
            .receive_timeout(Duration::from_millis(10))
            .unwrap()
            .is_none());
    }
}
