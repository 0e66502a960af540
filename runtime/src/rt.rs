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

/// Holds a CPU wake-up latency limit (PM QoS `/dev/cpu_dma_latency`): while the returned file
/// stays open, the CPUs avoid idle states slower to leave than the limit, so the control loop's
/// wake-ups are not delayed by deep sleep states. Dropping it releases the limit.
#[derive(Debug)]
pub struct CpuLatencyGuard {
    _file: std::fs::File,
}

/// Ask the kernel to keep every CPU's wake-up latency at or below `limit_us` microseconds.
pub fn hold_cpu_latency(limit_us: u32) -> io::Result<CpuLatencyGuard> {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/cpu_dma_latency")?;
    // The device takes a binary 32-bit value.
    file.write_all(&(limit_us as i32).to_ne_bytes())?;
    Ok(CpuLatencyGuard { _file: file })
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

/// The SCHED_FIFO priority of the vision threads, `realtime.vision_priority` (`None` for 0:
/// SCHED_OTHER).
pub fn vision_fifo_priority(realtime: &videt_config::RealtimeConfig) -> Option<u8> {
    (realtime.vision_priority > 0).then_some(realtime.vision_priority)
}

/// Called first on a vision thread: SCHED_FIFO at `priority` when one is given. A refusal is
/// a warning (the thread then stays SCHED_OTHER), not an error.
pub fn enter_vision_priority(priority: Option<u8>) {
    if let Some(p) = priority {
        if let Err(e) = set_fifo(p) {
            tracing::warn!("the vision thread stays SCHED_OTHER (SCHED_FIFO {p}: {e})");
        }
    }
}

/// Make the calling thread SCHED_FIFO at `priority` (1..=99).
pub fn set_fifo(priority: u8) -> Result<(), String> {
    use thread_priority::unix::{
        set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
        ThreadSchedulePolicy,
    };
    use thread_priority::{ThreadPriority, ThreadPriorityValue};
    let value =
        ThreadPriorityValue::try_from(priority).map_err(|e| format!("priority {priority}: {e}"))?;
    set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    )
    .map_err(|e| format!("{e:?}"))
}

/// Give the calling thread a lower real-time priority (the vision thread), or leave it
/// SCHED_OTHER when `priority` is 0.
pub fn set_background_priority(priority: u8) -> Option<String> {
    if priority == 0 {
        return None;
    }
    set_fifo(priority)
        .err()
        .map(|e| format!("vision thread stays SCHED_OTHER: SCHED_FIFO {priority} refused ({e})"))
}

/// Warnings about the machine's real-time fitness: the control CPU not isolated, the kernel not
/// PREEMPT_RT.
pub fn platform_warnings(control_cpu: Option<usize>) -> Vec<String> {
    let mut warnings = Vec::new();
    let realtime_kernel = std::fs::read_to_string("/sys/kernel/realtime")
        .is_ok_and(|s| s.trim() == "1")
        || kernel_version().contains("PREEMPT_RT");
    if !realtime_kernel {
        warnings.push(
            "kernel is not PREEMPT_RT: expect occasional wake-up latencies of milliseconds; use a PREEMPT_RT kernel on the device".to_string(),
        );
    }
    if let Some(cpu) = control_cpu {
        let isolated =
            std::fs::read_to_string("/sys/devices/system/cpu/isolated").unwrap_or_default();
        if !cpu_list_contains(isolated.trim(), cpu) {
            warnings.push(format!(
                "control CPU {cpu} is not isolated (isolcpus/nohz_full): other tasks and interrupts share it"
            ));
        }
        warnings.extend(control_cpu_alone_warning(cpu, &allowed_cpus()));
    }
    warnings
}

/// The warning when the process may run on the control CPU alone (`allowed`, its affinity
/// mask): then every other thread of the service (vision, control socket, live view, the
/// watchdog's supervisor) gets only what the control thread leaves of that CPU. A 2-CPU machine
/// under the packaged unit's `CPUAffinity=1-3` is such a case.
pub fn control_cpu_alone_warning(control_cpu: usize, allowed: &[usize]) -> Option<String> {
    (allowed == [control_cpu]).then(|| {
        format!(
            "the service may run on CPU {control_cpu} only, the control CPU: its vision, socket, live-view and supervisor threads get only what the control thread leaves of it (late socket answers, watchdog restarts); allow it more CPUs (systemd's CPUAffinity=, taskset)"
        )
    })
}

/// The running kernel's version string (`uname -v`), from the system call: the service's
/// `/proc` may show only its own processes (`ProcSubset=pid`).
fn kernel_version() -> String {
    // SAFETY: `uname` fills the zeroed struct it is given; its fields are NUL-terminated.
    unsafe {
        let mut names: libc::utsname = std::mem::zeroed();
        if libc::uname(&mut names) != 0 {
            return String::new();
        }
        std::ffi::CStr::from_ptr(names.version.as_ptr())
            .to_string_lossy()
            .into_owned()
    }
}

/// Whether a kernel CPU list such as `1,3-5` contains `cpu`.
pub fn cpu_list_contains(list: &str, cpu: usize) -> bool {
    list.split(',')
        .filter(|p| !p.is_empty())
        .any(|part| match part.split_once('-') {
            Some((a, b)) => match (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
                (Ok(a), Ok(b)) => (a..=b).contains(&cpu),
                _ => false,
            },
            None => part.trim().parse::<usize>() == Ok(cpu),
        })
}

/// The CPUs the calling thread may run on, ascending: its affinity mask, which systemd's
/// `CPUAffinity=` or `taskset` narrow to some of the CPUs online (`CPUAffinity=1-3` leaves
/// 1, 2 and 3, not 0 to 2). A thread can be pinned to these only.
pub fn allowed_cpus() -> Vec<usize> {
    // SAFETY: cpu_set_t is plain data; sched_getaffinity writes at most its size into it;
    // CPU_ISSET reads inside it for indices below CPU_SETSIZE.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            let online = std::thread::available_parallelism().map_or(1, |n| n.get());
            return (0..online).collect();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&cpu| libc::CPU_ISSET(cpu, &set))
            .collect()
    }
}

/// Whether the calling thread may run on `cpu` (see [`allowed_cpus`]).
pub fn cpu_allowed(cpu: usize) -> bool {
    allowed_cpus().contains(&cpu)
}

/// `cpus` (ascending) as the kernel writes CPU lists: `0-2,5`.
pub fn cpu_list(cpus: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < cpus.len() {
        let start = cpus[i];
        while i + 1 < cpus.len() && cpus[i + 1] == cpus[i] + 1 {
            i += 1;
        }
        parts.push(if cpus[i] == start {
            start.to_string()
        } else {
            format!("{start}-{}", cpus[i])
        });
        i += 1;
    }
    parts.join(",")
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

/// CPU time of the calling thread (`CLOCK_THREAD_CPUTIME_ID`).
pub fn thread_cpu_time() -> std::time::Duration {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; the clock exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    std::time::Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32)
}

/// Keep the calling thread off `cpu` (the control thread's): its affinity becomes the CPUs it
/// may run on now without that one. A thread that does network or file I/O in system calls
/// then never runs kernel code on the control CPU, where a kernel without full preemption would
/// hold the control thread's wake-up until the call returns. Nothing changes when `cpu` is the
/// only CPU allowed; returns whether the mask changed.
pub fn keep_off_cpu(cpu: usize) -> bool {
    let others: Vec<usize> = allowed_cpus().into_iter().filter(|&c| c != cpu).collect();
    if others.is_empty() || !cpu_allowed(cpu) {
        return false;
    }
    // SAFETY: cpu_set_t is plain data; CPU_ZERO/CPU_SET only write inside it for indices below
    // CPU_SETSIZE (every index came from CPU_ISSET over that range); 0 = this thread.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_ZERO(&mut set);
        for c in others {
            libc::CPU_SET(c, &mut set);
        }
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
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
        let allowed = allowed_cpus();
        if !allowed.contains(&cpu) {
            report.warnings.push(format!(
                "control CPU {cpu} is not one this process may run on (CPUs {}: the machine's, or its CPUAffinity=); not pinned",
                cpu_list(&allowed)
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_process_confined_to_the_control_cpu_is_warned_of() {
        let alone = control_cpu_alone_warning(1, &[1]).expect("warned");
        assert!(
            alone.contains("CPU 1 only") && alone.contains("CPUAffinity="),
            "{alone}"
        );
        assert_eq!(control_cpu_alone_warning(1, &[1, 2, 3]), None);
        assert_eq!(control_cpu_alone_warning(1, &[0, 1]), None);
        // Not allowed at all is the pinning's own warning.
        assert_eq!(control_cpu_alone_warning(1, &[2]), None);
    }

    #[test]
    fn a_thread_kept_off_a_cpu_runs_on_the_others_only() {
        std::thread::spawn(|| {
            let allowed = allowed_cpus();
            let Some(&control) = allowed.last() else {
                return;
            };
            let changed = keep_off_cpu(control);
            if allowed.len() == 1 {
                assert!(!changed, "the only CPU is kept");
                assert_eq!(allowed_cpus(), allowed);
            } else {
                assert!(changed);
                let now = allowed_cpus();
                assert!(!now.contains(&control), "{now:?}");
                assert_eq!(now.len(), allowed.len() - 1);
            }
        })
        .join()
        .unwrap();
    }

    #[test]
    fn cpu_lists_are_written_as_the_kernel_writes_them() {
        assert_eq!(cpu_list(&[0, 1, 2, 5]), "0-2,5");
        assert_eq!(cpu_list(&[3]), "3");
        assert_eq!(cpu_list(&[1, 3, 4]), "1,3-4");
        assert_eq!(cpu_list(&[]), "");
    }

    /// Under an affinity mask that leaves out CPU 0 (systemd's `CPUAffinity=1-3` on the
    /// backpack), the control thread is pinned to a CPU of the mask, not refused because the
    /// mask holds fewer CPUs than that CPU's index.
    #[test]
    fn a_cpu_of_the_affinity_mask_is_allowed_whatever_its_index() {
        let all = allowed_cpus();
        assert!(!all.is_empty());
        assert!(!cpu_allowed(libc::CPU_SETSIZE as usize + 1));
        let Some(&last) = all.iter().rfind(|&&c| c > 0) else {
            eprintln!("skipped: this process may run on one CPU only ({all:?})");
            return;
        };
        std::thread::spawn(move || {
            pin_to_cpu(last).unwrap();
            assert_eq!(allowed_cpus(), vec![last]);
            assert!(cpu_allowed(last));
            assert!(!cpu_allowed(0));
            let report = setup_control_thread(1, Some(last));
            assert!(report.pinned, "{:?}", report.warnings);
            let report = setup_control_thread(1, Some(0));
            assert!(!report.pinned);
            assert!(
                report
                    .warnings
                    .iter()
                    .any(|w| w.contains("control CPU 0 is not one")
                        && w.contains(&format!("CPUs {last}"))),
                "{:?}",
                report.warnings
            );
        })
        .join()
        .unwrap();
    }

    #[test]
    fn the_kernel_version_from_uname_is_the_one_proc_shows() {
        let version = kernel_version();
        assert!(!version.is_empty());
        if let Ok(proc_version) = std::fs::read_to_string("/proc/sys/kernel/version") {
            assert_eq!(version, proc_version.trim());
        }
    }

    #[test]
    fn cpu_lists() {
        assert!(cpu_list_contains("1,3-5", 4));
        assert!(cpu_list_contains("1,3-5", 1));
        assert!(!cpu_list_contains("1,3-5", 2));
        assert!(!cpu_list_contains("", 0));
    }

    #[test]
    fn system_clock_is_monotonic_and_sleeps_to_the_deadline() {
        let mut c = SystemClock;
        let a = c.now();
        let deadline = a.add_nanos(2_000_000);
        c.sleep_until(deadline);
        assert!(c.now() >= deadline);
    }
}
