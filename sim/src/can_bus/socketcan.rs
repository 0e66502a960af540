//! The simulated nodes on a real kernel CAN interface (`vcan0`, `can0`, ...) through a raw
//! SocketCAN socket, so the drive driver under test talks to them through the kernel's CAN
//! stack as it talks to real drives.

use std::time::Duration;

use embedded_can::{ExtendedId, Frame, Id, StandardId};
use nix::poll::{ppoll, PollFd, PollFlags};
use socketcan::{CanFrame, CanSocket, EmbeddedFrame, Socket};

use super::{BusError, SimFrame};
use crate::cia402_node::SimPort;

/// A raw CAN socket on one interface, carrying [`SimFrame`]s.
#[derive(Debug)]
pub struct SocketCanEndpoint {
    socket: CanSocket,
}

impl SocketCanEndpoint {
    /// Open interface `ifname` (it must exist and be up).
    pub fn open(ifname: &str) -> std::io::Result<SocketCanEndpoint> {
        Ok(SocketCanEndpoint {
            socket: CanSocket::open(ifname)?,
        })
    }
}

/// A [`SimFrame`] as a kernel CAN frame.
pub fn to_kernel_frame(frame: &SimFrame) -> Option<CanFrame> {
    let id = frame.id();
    if frame.is_remote_frame() {
        CanFrame::new_remote(id, frame.dlc())
    } else {
        CanFrame::new(id, frame.data())
    }
}

/// A kernel CAN frame as a [`SimFrame`]; `None` for error and FD frames.
pub fn from_kernel_frame(frame: &CanFrame) -> Option<SimFrame> {
    let id: Id = match EmbeddedFrame::id(frame) {
        Id::Standard(s) => StandardId::new(s.as_raw())?.into(),
        Id::Extended(e) => ExtendedId::new(e.as_raw())?.into(),
    };
    match frame {
        CanFrame::Data(_) => SimFrame::new(id, EmbeddedFrame::data(frame)),
        CanFrame::Remote(_) => SimFrame::new_remote(id, EmbeddedFrame::dlc(frame)),
        CanFrame::Error(_) => None,
    }
}

fn io_error(e: &std::io::Error) -> BusError {
    match e.raw_os_error() {
        // ENETDOWN / ENODEV: the interface went down or away.
        Some(libc::ENETDOWN) | Some(libc::ENODEV) | Some(libc::ENXIO) => BusError::BusOff,
        _ => BusError::Io(e.kind()),
    }
}

impl SimPort for SocketCanEndpoint {
    fn send_frame(&mut self, frame: &SimFrame) -> Result<(), BusError> {
        let Some(kernel) = to_kernel_frame(frame) else {
            return Ok(());
        };
        match self.socket.write_frame(&kernel) {
            Ok(()) => Ok(()),
            // A full transmit queue drops the frame, as a controller without a free mailbox.
            Err(e) if e.raw_os_error() == Some(libc::ENOBUFS) => Ok(()),
            Err(e) => Err(io_error(&e)),
        }
    }

    fn receive_frame(&mut self, timeout: Duration) -> Result<Option<SimFrame>, BusError> {
        use std::os::fd::AsFd;
        // `ppoll`, to the nanosecond: `poll` (the socket's own timed read) counts whole
        // milliseconds and would spin on a sub-millisecond wait.
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let mut fds = [PollFd::new(self.socket.as_fd(), PollFlags::POLLIN)];
            match ppoll(&mut fds, Some(left.into()), None) {
                Ok(0) => return Ok(None),
                Ok(_) => break,
                Err(nix::errno::Errno::EINTR) => continue,
                Err(e) => return Err(io_error(&e.into())),
            }
        }
        match self.socket.read_frame() {
            Ok(f) => Ok(from_kernel_frame(&f)),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => Ok(None),
            Err(e) => Err(io_error(&e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_cross_to_the_kernel_format_and_back() {
        let frames = [
            SimFrame::standard(0x080, &[]).unwrap(),
            SimFrame::standard(0x201, &[0x0F, 0x00, 0x2C, 0x01]).unwrap(),
            SimFrame::standard(0x7FF, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
            SimFrame::new(ExtendedId::new(0x1ABC_DEF0).unwrap(), &[9]).unwrap(),
            SimFrame::new_remote(StandardId::new(0x701).unwrap(), 1).unwrap(),
        ];
        for f in frames {
            let k = to_kernel_frame(&f).unwrap();
            assert_eq!(from_kernel_frame(&k), Some(f), "{f:?}");
        }
    }

    #[test]
    #[ignore = "needs a vcan0 interface: runs in the kernel-in-the-loop guest (scripts/kernel-in-the-loop.sh)"]
    fn two_endpoints_on_vcan0_see_each_others_frames() {
        let mut a = SocketCanEndpoint::open("vcan0").unwrap();
        let mut b = SocketCanEndpoint::open("vcan0").unwrap();
        let f = SimFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
        a.send_frame(&f).unwrap();
        assert_eq!(b.receive_frame(Duration::from_secs(1)).unwrap(), Some(f));
        // A raw socket does not receive its own frames by default.
        assert_eq!(a.receive_frame(Duration::from_millis(50)).unwrap(), None);
    }
}
