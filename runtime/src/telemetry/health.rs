//! How the session log's writes are going: the writer's events as they happen, and its state
//! for the service's supervisor and the live view.

use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

/// What the writer has to say, as it happens; the service logs each
/// ([`super::TelemetryWriter::take_events`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum WriterEvent {
    /// The file system refused a write: from now on periods are counted as lost, and the
    /// writer tries again every [`super::RETRY_EVERY`].
    Failing {
        /// The error, as the system gave it.
        error: String,
    },
    /// Writing again after a failure.
    Writing {
        /// Period records lost while the writes failed.
        lost: u64,
        /// How long the writes failed.
        after: Duration,
    },
    /// Retention removed an older session log.
    Removed {
        /// The log.
        path: PathBuf,
        /// Its size, bytes.
        bytes: u64,
    },
    /// Retention could not remove an older session log, or read the directory.
    NotRemoved {
        /// The log (or the directory).
        path: PathBuf,
        /// Why.
        error: String,
    },
}

/// What the writer thread shares with the service.
#[derive(Default)]
pub(super) struct WriterHealth {
    /// Period records not written because the file system refused them.
    pub(super) lost: AtomicU64,
    /// The error while the writes fail.
    pub(super) failure: Mutex<Option<String>>,
    /// Events not yet taken by the service.
    pub(super) events: Mutex<Vec<WriterEvent>>,
    /// Bytes of the log on disk.
    pub(super) bytes: AtomicU64,
    /// The writer thread's CPU time so far (compressing and writing), nanoseconds.
    pub(super) cpu_ns: AtomicU64,
}

impl WriterHealth {
    pub(super) fn failing(&self, error: String) {
        *self.failure.lock().unwrap_or_else(PoisonError::into_inner) = Some(error.clone());
        self.event(WriterEvent::Failing { error });
    }

    pub(super) fn writing(&self, lost: u64, after: Duration) {
        *self.failure.lock().unwrap_or_else(PoisonError::into_inner) = None;
        self.event(WriterEvent::Writing { lost, after });
    }

    pub(super) fn failure(&self) -> Option<String> {
        self.failure
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    pub(super) fn take_events(&self) -> Vec<WriterEvent> {
        std::mem::take(&mut *self.events.lock().unwrap_or_else(PoisonError::into_inner))
    }

    pub(super) fn event(&self, event: WriterEvent) {
        self.events
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(event);
    }
}

/// How the session log's writes are going, for another thread (the live view): a cheap
/// clone of the writer's own state.
#[derive(Clone)]
pub struct SessionLogHealth(pub(super) Arc<WriterHealth>);

impl SessionLogHealth {
    /// Period records lost so far because the file system refused them.
    pub fn lost(&self) -> u64 {
        self.0.lost.load(Ordering::Relaxed)
    }
    /// The error while the writes fail (`None`: writing).
    pub fn failure(&self) -> Option<String> {
        self.0.failure()
    }
    /// Bytes of the log on disk.
    pub fn bytes(&self) -> u64 {
        self.0.bytes.load(Ordering::Relaxed)
    }
    /// The writer thread's CPU time so far, as of its last write.
    pub fn writer_cpu(&self) -> Duration {
        Duration::from_nanos(self.0.cpu_ns.load(Ordering::Relaxed))
    }
    /// What the writer said since the last call, oldest first (also after it finished: what
    /// retention removed as the session closed).
    pub fn take_events(&self) -> Vec<WriterEvent> {
        self.0.take_events()
    }
}
