//! Shared pieces of the whole-stack tests.

use videt_runtime::control_loop::{CycleObserver, WindowStats};
use videt_runtime::cycle::CycleRecord;

/// Keeps every period's record, up to the capacity it was created with (it never grows on the
/// control thread).
pub struct Recorder(pub Vec<CycleRecord>);

impl CycleObserver for Recorder {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        if self.0.len() < self.0.capacity() {
            self.0.push(*record);
        }
    }
}
