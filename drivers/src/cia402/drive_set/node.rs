//! What the set knows of each drive: the link to one node, kept up to date by the frames the
//! set receives (heartbeat, EMCY, process data), with its position unwrapped and, without a
//! velocity in TPDO1, its velocity derived from the positions of successive SYNCs.

use std::time::Instant;

use crate::cia402::pdo::{Motion, Status};
use crate::cia402::state::PowerState;

/// What the host knows of one drive.
#[derive(Debug, Clone, Copy)]
pub(super) struct NodeLink {
    pub(super) id: u8,
    /// The wire this drive moves (its index in the configuration's node ids).
    pub(super) wire: u8,
    pub(super) last_heard: Instant,
    pub(super) nmt_state: u8,
    pub(super) booted: bool,
    pub(super) rebooted: bool,
    pub(super) emcy: Option<(u16, u8)>,
    pub(super) motion: Motion,
    pub(super) status: Status,
    pub(super) analog_input: i16,
    pub(super) got_motion: bool,
    pub(super) got_status: bool,
    pub(super) status_heard: Option<Instant>,
    pub(super) missed: u32,
    /// Consecutive cycles this wire has wound faster than the trip speed.
    pub(super) overspeed_cycles: u32,
    pub(super) position_counts: i64,
    last_raw_position: Option<i32>,
    /// Without a velocity in TPDO1: the position (drive units, unwrapped) at a SYNC and when
    /// that SYNC was sent, and the velocity derived from the last two (drive units per second).
    velocity_base: Option<(i64, Instant)>,
    pub(super) derived_velocity: f64,
    /// -1 when the set itself negates this drive's position and velocity (its encoder is
    /// reversed and the drive has no polarity object), else 1.
    pub(super) encoder_sign: f64,
}

impl NodeLink {
    pub(super) fn new(id: u8, wire: usize, now: Instant) -> NodeLink {
        NodeLink {
            id,
            wire: wire as u8,
            last_heard: now,
            nmt_state: 0xFF,
            booted: false,
            rebooted: false,
            emcy: None,
            motion: Motion::default(),
            status: Status::default(),
            analog_input: 0,
            got_motion: false,
            got_status: false,
            status_heard: None,
            missed: 0,
            overspeed_cycles: 0,
            position_counts: 0,
            last_raw_position: None,
            velocity_base: None,
            derived_velocity: 0.0,
            encoder_sign: 1.0,
        }
    }

    /// Unwrap a 32-bit position into the running count.
    pub(super) fn track_position(&mut self, raw: i32) {
        let delta = match self.last_raw_position {
            Some(prev) => i64::from(raw.wrapping_sub(prev)),
            None => i64::from(raw),
        };
        self.position_counts += delta;
        self.last_raw_position = Some(raw);
    }

    /// Derive the velocity from the position sampled at the SYNC sent at `sync_at` and the
    /// one before (over the time between the two SYNCs, whatever the host's wake-ups).
    pub(super) fn derive_velocity(&mut self, sync_at: Instant) {
        if let Some((base, base_at)) = self.velocity_base {
            let dt = sync_at.saturating_duration_since(base_at).as_secs_f64();
            if dt > 0.0 {
                self.derived_velocity = (self.position_counts - base) as f64 / dt;
            }
        }
        self.velocity_base = Some((self.position_counts, sync_at));
    }

    pub(super) fn power_state(&self) -> PowerState {
        PowerState::from_statusword(self.status.statusword)
    }

    /// Whether this cycle's process data is in: the motion of this cycle, and the status of
    /// this cycle when it is synchronous (`status_every_sync`), or ever heard when it is
    /// event-driven (its age is checked against the heartbeat timeout).
    pub(super) fn has_cycle_data(&self, status_every_sync: bool) -> bool {
        self.got_motion
            && if status_every_sync {
                self.got_status
            } else {
                self.status_heard.is_some()
            }
    }
}
