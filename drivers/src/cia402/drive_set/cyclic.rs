//! The exchange of every control period: SYNC, the drives' TPDOs awaited until `pdo_timeout`,
//! the drives checked (heartbeat, NMT state, EMCY, missed cycles, fault), the samples handed to
//! the HAL, the torque limited before it is sent, and the safe state latched on any failure.
//! Allocation-free; it blocks only in the bus receive, never past `pdo_timeout`. The sequences
//! that cycle it outside the control loop wait out each period with `sleep_rest_of_cycle`.

use std::time::{Duration, Instant};

use videt_hal::{DriveSample, LifecycleState};

use super::Cia402DriveSet;
use crate::can::CanPort;
use crate::canopen::cob;
use crate::cia402::error::DriveError;
use crate::cia402::pdo::Command;
use crate::cia402::state::{controlword, PowerState};

/// Most frames handled in one cycle (bounds the receive loop): 64, and 16 per drive beyond
/// four drives.
const fn max_frames_per_cycle(drives: usize) -> usize {
    if drives > 4 {
        16 * drives
    } else {
        64
    }
}

/// NMT state byte of "operational".
const NMT_OPERATIONAL: u8 = 0x05;

impl<P: CanPort, const N: usize> Cia402DriveSet<P, N> {
    /// SYNC, collect the TPDOs, check the drives. **RT**.
    pub(super) fn exchange(&mut self, strict_faults: bool) -> Result<(), DriveError> {
        // Frames still queued belong to earlier cycles (late or unsolicited).
        for _ in 0..max_frames_per_cycle(N) {
            match self.receive(Duration::ZERO)? {
                Some(f) => self.absorb(&f, false, Instant::now()),
                None => break,
            }
        }
        for n in &mut self.nodes {
            n.got_motion = false;
            n.got_status = false;
        }
        let start = Instant::now();
        self.sync_sent_at = start;
        self.send(cob::SYNC, &[])?;
        if start >= self.host_heartbeat_due {
            let host = cob::HEARTBEAT_BASE + u16::from(self.cfg.host_node_id);
            self.send(host, &[NMT_OPERATIONAL])?;
            self.host_heartbeat_due =
                start + Duration::from_millis(u64::from(self.cfg.host_heartbeat_ms));
        }
        let deadline = start + self.cfg.pdo_timeout;
        let status_every_sync = self.cfg.analog_input.is_some();
        for _ in 0..max_frames_per_cycle(N) {
            if self
                .nodes
                .iter()
                .all(|n| n.has_cycle_data(status_every_sync))
            {
                break;
            }
            let now = Instant::now();
            if now >= deadline {
                break;
            }
            match self.receive(deadline - now)? {
                Some(f) => self.absorb(&f, true, Instant::now()),
                None => break,
            }
        }
        if let Some(analog) = &self.analog {
            for (wire, node) in self.nodes.iter().enumerate() {
                if node.got_status {
                    analog.publish(wire, node.analog_input);
                }
            }
        }
        self.check_nodes(strict_faults, Instant::now())
    }

    fn check_nodes(&mut self, strict_faults: bool, now: Instant) -> Result<(), DriveError> {
        let hb_timeout = self.cfg.drive_heartbeat_timeout;
        let max_missed = self.cfg.max_missed_cycles;
        let status_every_sync = self.cfg.analog_input.is_some();
        for node in &mut self.nodes {
            if node.rebooted {
                return Err(DriveError::NotOperational {
                    wire: node.wire,
                    node: node.id,
                    nmt_state: 0,
                });
            }
            if strict_faults {
                if let Some((code, register)) = node.emcy {
                    return Err(DriveError::Emergency {
                        wire: node.wire,
                        node: node.id,
                        code,
                        register,
                    });
                }
            }
            let silent = now.saturating_duration_since(node.last_heard);
            if silent > hb_timeout {
                return Err(DriveError::HeartbeatLost {
                    wire: node.wire,
                    node: node.id,
                    silent_ms: silent.as_millis() as u64,
                });
            }
            if node.nmt_state != NMT_OPERATIONAL {
                return Err(DriveError::NotOperational {
                    wire: node.wire,
                    node: node.id,
                    nmt_state: node.nmt_state,
                });
            }
            if node.has_cycle_data(status_every_sync) {
                node.missed = 0;
            } else {
                node.missed += 1;
                if node.missed > max_missed {
                    return Err(DriveError::PdoTimeout {
                        wire: node.wire,
                        node: node.id,
                        missed_cycles: node.missed,
                    });
                }
            }
            if strict_faults && node.power_state() == PowerState::Fault {
                return Err(DriveError::DriveFault {
                    wire: node.wire,
                    node: node.id,
                    error_code: node.status.error_code,
                });
            }
        }
        Ok(())
    }

    /// Latch `e`, command every drive off with zero torque, and return `e`. **RT**.
    pub(super) fn fail(&mut self, e: DriveError) -> DriveError {
        if self.latched.is_none() {
            self.latched = Some(e);
            if let Some(reports) = self.fault_reports.as_mut() {
                // A full queue means an unread backlog: the newest error is the one dropped.
                let _ = reports.push(e);
            }
        }
        self.lifecycle = LifecycleState::Faulted;
        self.send_safe_commands();
        e
    }

    pub(super) fn send_safe_commands(&mut self) {
        let off = Command {
            controlword: controlword::DISABLE_VOLTAGE,
            target_torque_permille: 0,
        }
        .encode();
        for i in 0..N {
            let cob = cob::RPDO_BASE[0] + u16::from(self.nodes[i].id);
            let _ = self.send(cob, &off);
        }
    }

    pub(super) fn sample(&self, i: usize) -> DriveSample {
        let n = &self.nodes[i];
        let sign = n.encoder_sign;
        DriveSample {
            position_counts: (sign * n.position_counts as f64 * self.cfg.counts_per_position_unit)
                .round() as i64,
            velocity_counts_per_s: sign
                * if self.cfg.analog_input.is_some() {
                    n.derived_velocity * self.cfg.counts_per_position_unit
                } else {
                    f64::from(n.motion.velocity) * self.cfg.counts_per_s_per_velocity_unit
                },
            state: n.power_state().to_hal(),
            error_code: n.status.error_code,
        }
    }

    /// The torque actually sent for wire `i`: clamped to ±torque(t_max), cut when the wire
    /// already runs faster than the speed limit in the torque's direction; a winding speed
    /// above the trip speed for `overspeed_trip_cycles` cycles in a row is an error. **RT**.
    pub(super) fn limited_torque(&mut self, i: usize, torque_nm: f64) -> Result<f64, DriveError> {
        if !torque_nm.is_finite() {
            return Err(DriveError::InvalidTorque { wire: i });
        }
        let limit = self.cfg.max_torque_nm();
        let t = torque_nm.clamp(-limit, limit);
        let speed = self
            .cfg
            .transmission
            .wire_speed(self.sample(i).velocity_counts_per_s);
        let max = self.cfg.max_wire_speed_m_per_s;
        // Only winding is driven by the motor: a wire wound in faster than the trip speed
        // despite the cut torque is a drive or encoder fault. Fast unwinding is the operator
        // pulling the thimble away, which the motor merely resists.
        let node = &mut self.nodes[i];
        if speed > max * self.cfg.overspeed_trip_factor {
            node.overspeed_cycles += 1;
            if node.overspeed_cycles >= self.cfg.overspeed_trip_cycles {
                return Err(DriveError::OverSpeed {
                    wire: i,
                    speed_mm_per_s: (speed * 1000.0) as i32,
                });
            }
        } else {
            node.overspeed_cycles = 0;
        }
        if speed.abs() > max && t * speed > 0.0 {
            return Ok(0.0);
        }
        Ok(t)
    }

    /// Sleep out the control period begun at `cycle_start`, for the sequences that run the
    /// exchange outside the control loop (start-up, power sequencing); never on the RT path.
    pub(super) fn sleep_rest_of_cycle(&self, cycle_start: Instant) {
        let end = cycle_start + self.cfg.control_period;
        let now = Instant::now();
        if end > now {
            std::thread::sleep(end - now);
        }
    }
}
