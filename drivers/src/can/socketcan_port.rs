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

/// Wait until `fd` is readable or `timeout` has passed, to the nanosecond: `ppoll`, because
/// `poll` counts whole milliseconds and a sub-millisecond wait (a PDO window at 1 kHz) would
/// not wait at all. `Ok(false)` on timeout; a signal restarts the wait with what remains.
pub fn wait_readable(fd: std::os::fd::BorrowedFd<'_>, timeout: Duration) -> std::io::Result<bool> {
    use nix::poll::{ppoll, PollFd, PollFlags};
    let deadline = std::time::Instant::now() + timeout;
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        let mut fds = [PollFd::new(fd, PollFlags::POLLIN)];
        match ppoll(&mut fds, Some(left.into()), None) {
            Ok(n) => return Ok(n > 0),
            Err(nix::errno::Errno::EINTR) => continue,
            Err(e) => return Err(e.into()),
        }
    }
}

impl CanPort for SocketCanPort {
    fn receive_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, socketcan::Error> {
        use std::os::fd::AsFd;
        match wait_readable(self.socket.as_fd(), timeout) {
            Ok(true) => {}
            Ok(false) => return Ok(None),
            Err(e) => return Err(socketcan::Error::from(e)),
        }
        match self.socket.read_frame() {
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

    fn os_error(error: &socketcan::Error) -> Option<i32> {
        match error {
            socketcan::Error::Io(e) => e.raw_os_error(),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interface_gone_down_is_told_in_the_systems_words() {
        let down = socketcan::Error::from(std::io::Error::from_raw_os_error(
            nix::errno::Errno::ENETDOWN as i32,
        ));
        let errno = SocketCanPort::os_error(&down).expect("an OS error");
        let told = crate::cia402::DriveError::BusIo { errno }.to_string();
        assert!(told.contains("CAN interface: Network is down"), "{told}");
        // An error that did not come from the system has no number to tell.
        let other = socketcan::Error::from(std::io::Error::other("not from the system"));
        assert_eq!(SocketCanPort::os_error(&other), None);
    }

    #[test]
    #[ignore = "needs a vcan0 interface (ip link add dev vcan0 type vcan && ip link set up vcan0): runs in the kernel-in-the-loop guest"]
    fn opens_vcan_and_times_out_without_traffic() {
        let mut p = SocketCanPort::open("vcan0").unwrap();
        assert!(p
            .receive_timeout(Duration::from_millis(10))
            .unwrap()
            .is_none());
    }

    #[test]
    #[ignore = "needs a vcan0 interface (ip link add dev vcan0 type vcan && ip link set up vcan0): runs in the kernel-in-the-loop guest"]
    fn a_sub_millisecond_timeout_waits_for_its_whole_length() {
        // A PDO window at 1 kHz is 0.6 ms: `poll` would round it down to no wait at all.
        let mut p = SocketCanPort::open("vcan0").unwrap();
        for us in [300u64, 600, 900] {
            let t = std::time::Instant::now();
            assert!(p
                .receive_timeout(Duration::from_micros(us))
                .unwrap()
                .is_none());
            assert!(t.elapsed() >= Duration::from_micros(us), "{us} µs");
        }
    }

    #[test]
    fn waiting_on_a_quiet_descriptor_takes_the_whole_sub_millisecond_timeout() {
        use std::os::fd::AsFd;
        let (a, _b) = std::os::unix::net::UnixStream::pair().unwrap();
        let t = std::time::Instant::now();
        assert!(!wait_readable(a.as_fd(), Duration::from_micros(600)).unwrap());
        assert!(t.elapsed() >= Duration::from_micros(600));
        let (c, mut d) = std::os::unix::net::UnixStream::pair().unwrap();
        std::io::Write::write_all(&mut d, b"x").unwrap();
        assert!(wait_readable(c.as_fd(), Duration::from_micros(600)).unwrap());
    }
}
