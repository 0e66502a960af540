//! Real-time process set-up and the system monotonic clock.
//!
//! Where the process lacks the rights (no `CAP_SYS_NICE`, a low `RLIMIT_MEMLOCK`), each step
//! warns clearly and the run goes on degraded: the loop still runs, with worse latency.

use std::io;

use videt_hal::{Clock, MonoTime};

/// `CLOCK_MONOTONIC` with absolute-time sleeps (`clock_nanosleep(TIMER_ABSTIME)`).
#[derive(Debug, Clone, Copy, Default)]
pub struct SystemClock;

impl Clock for SystemClock {
    fn now(&self) -> MonoTime {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC always exists on Linux.
        unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        MonoTime(ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64)
    }

    fn sleep_until(&mut self, deadline: MonoTime) {
        let ts = libc::timespec {
            tv_sec: (deadline.0 / 1_000_000_000) as libc::time_t,
            tv_nsec: (deadline.0 % 1_000_000_000) as libc::c_long,
        };
        loop {
            // SAFETY: `ts` is a valid timespec; a null remainder is allowed with TIMER_ABSTIME.
            let rc = unsafe {
                libc::clock_nanosleep(
                    libc::CLOCK_MONOTONIC,
                    libc::TIMER_ABSTIME,
                    &ts,
                    std::ptr::null_mut(),
                )
            };
            if rc != libc::EINTR {
                break;
            }
        }
    }
}

/// What the real-time set-up achieved, for the log and the status.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct RtReport {
    /// Memory is locked.
    pub memory_locked: bool,
    /// The calling thread runs SCHED_FIFO.
    pub fifo: bool,
    /// The calling thread is pinned to the requested CPU.
    pub pinned: bool,
    /// Warnings, one per degraded step.
    pub warnings: Vec<String>,
}

/// Lock current and future memory (`mlockall(MCL_CURRENT | MCL_FUTURE)`).
pub fn lock_memory() -> io::Result<()> {
    // SAFETY: plain syscall without pointers.
    let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Touch `bytes` of stack so the pages are resident before the loop starts.
#[inline(never)]
pub fn prefault_stack(bytes: usize) {
    const CHUNK: usize = 16 * 1024;
    fn touch(remaining: usize) {
        let mut buf = [0u8; CHUNK];
        std::hint::black_box(&mut buf);
        if remaining > CHUNK {
            touch(remaining - CHUNK);
        }
    }
    touch(bytes);
}

/// Make the calling thread SCHED_FIFO at `priority` (1..=99).
pub fn set_fifo(priority: u8) -> io::Result<()> {
    let param = libc::sched_param {
        sched_priority: i32::from(priority),
    };
    // SAFETY: `param` is a valid sched_param; 0 means the calling thread.
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc == 0 {
        Ok(())
    } else {
        Err(io::Error::last_os_error())
    }
}

/// Pin the calling thread to `cpu`.
pub fn pin_to_cpu(cpu: usize) -> io::Result<()> {
    // SAFETY: cpu_set_t is plain data; CPU_ZERO/CPU_SET only write inside it; 0 = this thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_ZERO(&mut set);
        libc::CPU_SET(cpu, &mut set);
        if libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0 {
            Ok(())
        } else {
            Err(io::Error::last_os_error())
        }
    }
}

/// Set the calling (control) thread up for real time: FIFO priority, CPU pinning, a prefaulted
/// stack. Each failure is a warning, never an error.
pub fn setup_control_thread(priority: u8, cpu: Option<usize>) -> RtReport {
    let mut report = RtReport::default();
    match set_fifo(priority) {
        Ok(()) => report.fifo = true,
        Err(e) => report.warnings.push(format!(
            "control thread stays SCHED_OTHER: SCHED_FIFO {priority} refused ({e}); grant CAP_SYS_NICE or LimitRTPRIO, latency will be worse"
        )),
    }
    if let Some(cpu) = cpu {
        let online = std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1);
        if cpu >= online {
            report.warnings.push(format!(
                "control CPU {cpu} does not exist ({online} CPUs online); not pinned"
            ));
        } else {
            match pin_to_cpu(cpu) {
                Ok(()) => report.pinned = true,
                Err(e) => report
                    .warnings
                    .push(format!("control thread not pinned to CPU {cpu}: {e}")),
            }
        }
    }
    prefault_stack(256 * 1024);
    report
}
