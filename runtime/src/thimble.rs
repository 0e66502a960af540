//! The thimble's state, published by the control thread every period for the vision and colour
//! threads (where to look: the region of interest follows the finger), through a snapshot
//! channel.

use crate::control_loop::{CycleObserver, WindowStats};
use crate::cycle::CycleRecord;
use crate::snapshot::{snapshot_channel, SnapshotReader, SnapshotWriter};

/// The thimble state the control thread publishes every period for the vision thread (where to
/// look: the region of interest follows the finger).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ThimbleState {
    /// Period number.
    pub cycle: u64,
    /// Time of the period, seconds.
    pub time_s: f64,
    /// Position, metres.
    pub position_m: [f64; 3],
    /// Velocity, m/s.
    pub velocity_m_s: [f64; 3],
    /// Touching the surface.
    pub in_contact: bool,
}

/// Publishes the thimble state every period (wait-free, allocation-free).
pub struct ThimblePublisher(SnapshotWriter<ThimbleState>);

/// Creates the thimble-state channel.
pub fn thimble_channel() -> (ThimblePublisher, SnapshotReader<ThimbleState>) {
    let (w, r) = snapshot_channel(ThimbleState::default());
    (ThimblePublisher(w), r)
}

impl CycleObserver for ThimblePublisher {
    fn observe(&mut self, record: &CycleRecord, _window: &WindowStats) {
        let state = ThimbleState {
            cycle: record.cycle,
            time_s: record.time.as_secs_f64(),
            position_m: record.position_m,
            velocity_m_s: record.velocity_m_s,
            in_contact: record.in_contact,
        };
        self.0.publish_with(|slot| *slot = state);
    }
}
