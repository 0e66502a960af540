//! The two ends through which a procedure run by the service talks to the socket's client
//! thread: a preallocated wait-free ring of [`ProcedureEvent`]s (control thread → client) and a
//! few atomics (client → control thread), made once when the service starts; and the one
//! procedure slot a client takes ([`ProcedurePort::begin`]).

use std::cell::RefCell;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use videt_runtime::WIREMAN_WIRES;

use videt_config::Config;
use videt_control::autoinit::Stage;

use super::commission::{CommissionStep, RigCheck};
use super::session::{InitError, Measurement, Request};
use super::twin::SimFault;

/// Events the ring holds: a whole procedure's stages, messages and prompts fit many times over.
pub const EVENT_RING: usize = 256;
/// Bytes of a progress message carried by an event (longer ones are cut at a character).
pub const MESSAGE_BYTES: usize = 240;

/// Which procedure.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ProcedureKind {
    /// Auto-initialization (`videt init`).
    Initialize,
    /// Wire replacement (`videt wire replace N`), then auto-initialization.
    ReplaceWire {
        /// The wire.
        wire: usize,
        /// The usable length the new yarn needs, metres.
        required_length_m: f64,
    },
    /// The commissioning check of the rig (`videt commission`).
    Commission,
}

impl ProcedureKind {
    /// `init`, `wire-replace` or `commission`.
    pub fn name(&self) -> &'static str {
        KIND_NAMES[usize::from(self.code()) - 1]
    }

    /// The kind's code in [`ProcedurePort`]'s slot (1, 2, 3; 0 is no procedure).
    fn code(&self) -> u8 {
        match self {
            ProcedureKind::Initialize => 1,
            ProcedureKind::ReplaceWire { .. } => 2,
            ProcedureKind::Commission => 3,
        }
    }
}

/// The names of the procedure kinds, by code minus one.
const KIND_NAMES: [&str; 3] = ["init", "wire-replace", "commission"];

/// A procedure a client asked for, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct ProcedureSpec {
    /// Which one.
    pub kind: ProcedureKind,
    /// The manual steps are already done: do not wait for the client's confirmations.
    pub yes: bool,
    /// On the twin: seed of where the simulated technician connects the thimble.
    pub sim_seed: u64,
    /// On the twin: faults to rehearse.
    pub sim_faults: Vec<SimFault>,
    /// On the twin: usable length of the new yarn, metres.
    pub sim_new_wire_length_m: Option<f64>,
}

/// A progress message in a fixed buffer (no allocation to pass it on).
#[derive(Clone, Copy)]
pub struct Text {
    bytes: [u8; MESSAGE_BYTES],
    len: usize,
}

impl Text {
    /// `message`, cut at a character boundary to [`MESSAGE_BYTES`].
    pub fn new(message: &str) -> Text {
        let mut len = message.len().min(MESSAGE_BYTES);
        while !message.is_char_boundary(len) {
            len -= 1;
        }
        let mut bytes = [0u8; MESSAGE_BYTES];
        bytes[..len].copy_from_slice(&message.as_bytes()[..len]);
        Text { bytes, len }
    }
    /// The text.
    pub fn as_str(&self) -> &str {
        // Built from a `&str` cut at a character boundary.
        core::str::from_utf8(&self.bytes[..self.len]).unwrap_or("")
    }
}

impl core::fmt::Debug for Text {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        core::fmt::Debug::fmt(self.as_str(), f)
    }
}

/// What the control thread tells the client while a procedure runs.
#[derive(Debug)]
pub enum ProcedureEvent {
    /// The forces are ramped out and the procedure has the hardware.
    Started {
        /// Which procedure.
        kind: ProcedureKind,
        /// The hardware is the digital twin (its technician does the manual steps).
        twin: bool,
    },
    /// A stage of the procedure began.
    Stage {
        /// The stage.
        stage: Stage,
        /// Encoder counts.
        counts: [i64; WIREMAN_WIRES],
        /// Measured tensions, N.
        tension_n: [f64; WIREMAN_WIRES],
    },
    /// Readings, a few times a second.
    Progress {
        /// Seconds since the procedure started.
        elapsed_s: f64,
        /// Wire paid out since the procedure started, metres.
        travel_m: [f64; WIREMAN_WIRES],
        /// Measured tensions, N.
        tension_n: [f64; WIREMAN_WIRES],
    },
    /// A message (stage descriptions, results), as the tool prints them.
    Message(Text),
    /// A manual step.
    Prompt {
        /// The step.
        request: Request,
        /// The client must confirm it is done (`{"cmd":"continue"}`); false on the twin (its
        /// technician does it) and with `yes`.
        confirm: bool,
    },
    /// A manual step of the commissioning check.
    CheckPrompt {
        /// The step.
        step: CommissionStep,
        /// The client must confirm it is done; false on the twin and with `yes`.
        confirm: bool,
    },
    /// The procedure ended: what it measured (the client computes the workspace and saves the
    /// calibration), or why it failed.
    Finished(Box<Result<Measurement, InitError>>),
    /// The commissioning check ended: its steps, and what stopped it early.
    Checked(Box<RigCheck>),
}

/// Whether the client saved the calibration ([`ProcedureControl::saved`]).
pub mod saved {
    /// Not yet told.
    pub const PENDING: u8 = 0;
    /// Written (atomically, the previous kept as backup): use it.
    pub const SAVED: u8 = 1;
    /// Being written by the client thread.
    pub const SAVING: u8 = 3;
    /// Not written (write error, or the client left): keep the previous calibration.
    pub const NOT_SAVED: u8 = 2;
}

/// Signals from the client side to the control thread (atomics: wait-free both ways).
#[derive(Debug, Default)]
pub struct ProcedureControl {
    /// Abort the procedure (the client left or cancelled, the service is stopping).
    pub cancel: AtomicBool,
    /// Manual steps the client confirmed, counted.
    pub confirmations: AtomicU32,
    /// [`saved`] state of the result.
    pub saved: AtomicU8,
    /// The control thread is in procedure mode.
    pub running: AtomicBool,
}

/// The control thread's end of the pair.
pub struct ProcedureHandle {
    pub(crate) events: RefCell<rtrb::Producer<ProcedureEvent>>,
    pub(crate) spec: Arc<Mutex<Option<ProcedureSpec>>>,
    pub(crate) control: Arc<ProcedureControl>,
}

/// The socket's end of the pair, with what the client thread needs to check requests and save
/// the result.
pub struct ProcedurePort {
    /// The service's configuration.
    pub config: Config,
    /// Where the service's calibration lives.
    pub calibration_path: PathBuf,
    /// The hardware is the digital twin.
    pub twin: bool,
    busy: AtomicBool,
    kind: AtomicU8,
    events: Mutex<rtrb::Consumer<ProcedureEvent>>,
    spec: Arc<Mutex<Option<ProcedureSpec>>>,
    /// Why a procedure left the service in a safe state, for its supervisor to tell.
    cause: Mutex<Option<String>>,
    /// The shared signals.
    pub control: Arc<ProcedureControl>,
}

/// The pair, made once when the service starts.
pub fn procedure_channel(
    config: Config,
    calibration_path: PathBuf,
    twin: bool,
) -> (ProcedurePort, ProcedureHandle) {
    let (producer, consumer) = rtrb::RingBuffer::new(EVENT_RING);
    let spec = Arc::new(Mutex::new(None));
    let control = Arc::new(ProcedureControl::default());
    (
        ProcedurePort {
            config,
            calibration_path,
            twin,
            busy: AtomicBool::new(false),
            kind: AtomicU8::new(0),
            events: Mutex::new(consumer),
            spec: Arc::clone(&spec),
            cause: Mutex::new(None),
            control: Arc::clone(&control),
        },
        ProcedureHandle {
            events: RefCell::new(producer),
            spec,
            control,
        },
    )
}

/// Held by the client thread that runs the one procedure at a time; dropping it frees the slot.
pub struct ProcedureSession<'a> {
    port: &'a ProcedurePort,
    events: std::sync::MutexGuard<'a, rtrb::Consumer<ProcedureEvent>>,
}

impl ProcedurePort {
    /// Take the one procedure slot, or `None` when a procedure is running already.
    pub fn begin(&self) -> Option<ProcedureSession<'_>> {
        if self
            .busy
            .compare_exchange(false, true, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return None;
        }
        let Ok(mut events) = self.events.lock() else {
            self.busy.store(false, Ordering::Release);
            return None;
        };
        // Whatever a cancelled earlier run left behind.
        while events.pop().is_ok() {}
        self.control.cancel.store(false, Ordering::Release);
        self.control.saved.store(saved::PENDING, Ordering::Release);
        Some(ProcedureSession { port: self, events })
    }

    /// A procedure is running (a client holds the slot).
    pub fn busy(&self) -> bool {
        self.busy.load(Ordering::Acquire)
    }

    /// Say why the procedure that ended leaves the service in a safe state (the client
    /// thread, off the control thread).
    pub fn tell_cause(&self, cause: String) {
        if let Ok(mut c) = self.cause.lock() {
            *c = Some(cause);
        }
    }

    /// The cause a procedure told, once (the supervisor).
    pub fn take_cause(&self) -> Option<String> {
        self.cause.lock().ok().and_then(|mut c| c.take())
    }

    /// The procedure running, by name (`init`, `wire-replace`, `commission`).
    pub fn current(&self) -> Option<&'static str> {
        let code = usize::from(self.kind.load(Ordering::Acquire));
        code.checked_sub(1).and_then(|k| KIND_NAMES.get(k).copied())
    }
}

impl ProcedureSession<'_> {
    /// Hand `spec` to the control thread (it takes it on the hand-over).
    pub fn submit(&mut self, spec: ProcedureSpec) {
        self.port.kind.store(spec.kind.code(), Ordering::Release);
        if let Ok(mut slot) = self.port.spec.lock() {
            *slot = Some(spec);
        }
    }
    /// Take the spec back if the control thread has not taken it: true when withdrawn.
    pub fn withdraw(&mut self) -> bool {
        self.port
            .spec
            .lock()
            .map(|mut s| s.take().is_some())
            .unwrap_or(false)
    }
    /// The next event, if any.
    pub fn next_event(&mut self) -> Option<ProcedureEvent> {
        self.events.pop().ok()
    }
    /// The shared signals.
    pub fn control(&self) -> &ProcedureControl {
        &self.port.control
    }
}

impl Drop for ProcedureSession<'_> {
    fn drop(&mut self) {
        self.port.kind.store(0, Ordering::Release);
        self.port.busy.store(false, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_cut_at_a_character_boundary() {
        let long = "é".repeat(MESSAGE_BYTES);
        let t = Text::new(&long);
        assert!(t.as_str().len() <= MESSAGE_BYTES);
        assert!(t.as_str().chars().all(|c| c == 'é'));
        assert_eq!(Text::new("homing").as_str(), "homing");
    }

    #[test]
    fn one_procedure_at_a_time() {
        let (port, _handle) = procedure_channel(Config::default(), "c.toml".into(), true);
        let first = port.begin().expect("free");
        assert!(port.busy());
        assert!(port.begin().is_none(), "a second one is refused");
        drop(first);
        assert!(!port.busy());
        assert!(port.begin().is_some());
    }

    #[test]
    fn the_submitted_procedure_is_reported_by_its_name_until_the_session_ends() {
        let (port, _handle) = procedure_channel(Config::default(), "c.toml".into(), true);
        for kind in [
            ProcedureKind::Initialize,
            ProcedureKind::ReplaceWire {
                wire: 1,
                required_length_m: 2.0,
            },
            ProcedureKind::Commission,
        ] {
            let mut session = port.begin().expect("free");
            assert_eq!(port.current(), None, "nothing submitted yet");
            let name = kind.name();
            session.submit(ProcedureSpec {
                kind,
                yes: true,
                sim_seed: 0,
                sim_faults: Vec::new(),
                sim_new_wire_length_m: None,
            });
            assert_eq!(port.current(), Some(name));
            drop(session);
            assert_eq!(port.current(), None);
        }
        assert_eq!(ProcedureKind::Initialize.name(), "init");
        assert_eq!(ProcedureKind::Commission.name(), "commission");
        // A cause is told once.
        port.tell_cause("commissioning: drive2.encoder".into());
        assert_eq!(
            port.take_cause().as_deref(),
            Some("commissioning: drive2.encoder")
        );
        assert_eq!(port.take_cause(), None);
    }
}
