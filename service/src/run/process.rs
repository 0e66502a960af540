//! The process the service runs in: the panic hook that tells the control loop to go safe, the
//! real-time set-up (CPU wake-up latency, locked memory, the platform's warnings) and the
//! signals that stop it (SIGINT, SIGTERM) or are said to do nothing (SIGHUP).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use tracing::{error, warn};
use videt_config::Config;
use videt_runtime::control_loop::SERVICE_PANICKED;
use videt_runtime::rt;

/// Install a panic hook that, besides printing, tells the control loop to go safe and stop.
pub fn install_panic_hook() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        SERVICE_PANICKED.store(true, Ordering::SeqCst);
        default(info);
    }));
}

/// The CPU wake-up latency limit (`realtime.cpu_wakeup_latency_us`), held while the value
/// lives; memory locked (`realtime.lock_memory`); the platform's warnings for the control CPU
/// logged. What cannot be done is logged and the service runs on.
pub fn prepare(config: &Config) -> Option<rt::CpuLatencyGuard> {
    let cpu_latency = u32::try_from(config.realtime.cpu_wakeup_latency_us)
        .ok()
        .and_then(|limit| match rt::hold_cpu_latency(limit) {
            Ok(guard) => Some(guard),
            Err(e) => {
                warn!("CPU wake-up latency not limited (/dev/cpu_dma_latency: {e}); idle states may delay wake-ups");
                None
            }
        });
    if config.realtime.lock_memory {
        if let Err(e) = rt::lock_memory() {
            warn!("memory not locked (mlockall: {e}); page faults may delay the control loop");
        }
    }
    let control_cpu = usize::try_from(config.realtime.control_cpu).ok();
    for w in rt::platform_warnings(control_cpu) {
        warn!("{w}");
    }
    cpu_latency
}

/// The signals the service watches.
pub struct Signals {
    /// Raised by SIGINT or SIGTERM: ramp the forces out and stop.
    pub stop: Arc<AtomicBool>,
    /// The signal that raised `stop` (0: none), for the session log's end.
    pub signalled: Arc<AtomicUsize>,
    /// Raised by SIGHUP (a `systemctl reload`, a closed terminal), which would otherwise end
    /// the process without ramping the forces out.
    pub hangup: Arc<AtomicBool>,
}

impl Signals {
    /// Install the handlers; `None` (the error logged) when one cannot be.
    pub fn install() -> Option<Signals> {
        let stop = Arc::new(AtomicBool::new(false));
        let signalled = Arc::new(AtomicUsize::new(0));
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            let registered =
                signal_hook::flag::register_usize(signal, Arc::clone(&signalled), signal as usize)
                    .and_then(|_| signal_hook::flag::register(signal, Arc::clone(&stop)));
            if let Err(e) = registered {
                error!("cannot install the handler for signal {signal}: {e}");
                return None;
            }
        }
        let hangup = Arc::new(AtomicBool::new(false));
        if let Err(e) =
            signal_hook::flag::register(signal_hook::consts::SIGHUP, Arc::clone(&hangup))
        {
            error!("cannot install the handler for SIGHUP: {e}");
            return None;
        }
        Some(Signals {
            stop,
            signalled,
            hangup,
        })
    }
}
