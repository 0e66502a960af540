//! Checks of the host's own behaviour in a `candump` trace of a start-up and run (the frames
//! the host sent, whoever the drives were): every drive's communication reset before it is
//! configured over SDO, started only after its configuration, no SDO to a started drive, no
//! SYNC before the first start; and the figures a reader judges: the SYNC count and median
//! period, the host heartbeat's median period. **non-RT**.

use super::cob::{NMT, SDO_REQUEST_BASE, SYNC};
use super::trace::TraceFrame;

/// NMT command "start remote node".
const NMT_START: u8 = 0x01;
/// NMT command "reset communication".
const NMT_RESET_COMMUNICATION: u8 = 0x82;
/// NMT command "reset node".
const NMT_RESET_NODE: u8 = 0x81;

/// What a trace shows of the host.
#[derive(Debug, Clone, PartialEq)]
pub struct HostTrace {
    /// SYNC frames sent.
    pub syncs: usize,
    /// Median time between successive SYNCs, s (when the trace has timestamps and two SYNCs).
    pub sync_median_period_s: Option<f64>,
    /// Host heartbeats sent.
    pub heartbeats: usize,
    /// Median time between successive host heartbeats, s.
    pub heartbeat_median_period_s: Option<f64>,
    /// Shortest time between successive host heartbeats, s.
    pub heartbeat_min_period_s: Option<f64>,
    /// Nodes that were started (NMT start) after their configuration.
    pub started: Vec<u8>,
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

fn intervals(times: &[f64]) -> Vec<f64> {
    times.windows(2).map(|w| w[1] - w[0]).collect()
}

/// Check the host's behaviour towards `nodes` in `frames`; the host's heartbeat is
/// `0x700 + host_node_id`. An error names the trace line and the rule broken.
pub fn check_host_trace(
    frames: &[TraceFrame],
    nodes: &[u8],
    host_node_id: u8,
) -> Result<HostTrace, String> {
    // Per node: reset seen (and not yet started since), started.
    let mut reset = vec![false; nodes.len()];
    let mut started = vec![false; nodes.len()];
    let mut ever_started: Vec<u8> = Vec::new();
    let mut any_started = false;
    let (mut sync_times, mut syncs) = (Vec::new(), 0usize);
    let (mut heartbeat_times, mut heartbeats) = (Vec::new(), 0usize);
    let host_heartbeat = 0x700 + u16::from(host_node_id);
    for f in frames {
        let at = |what: &str| format!("trace line {}: {what}", f.line);
        match f.cob_id {
            NMT if f.data.len() == 2 => {
                let (command, target) = (f.data[0], f.data[1]);
                for (i, &n) in nodes.iter().enumerate() {
                    if target != 0 && target != n {
                        continue;
                    }
                    match command {
                        NMT_RESET_COMMUNICATION | NMT_RESET_NODE => {
                            reset[i] = true;
                            started[i] = false;
                        }
                        NMT_START => {
                            if !reset[i] {
                                return Err(at(&format!(
                                    "node {n} started without a communication reset first"
                                )));
                            }
                            started[i] = true;
                            any_started = true;
                            if !ever_started.contains(&n) {
                                ever_started.push(n);
                            }
                        }
                        _ => {}
                    }
                }
            }
            SYNC if f.data.is_empty() => {
                if !any_started {
                    return Err(at("SYNC sent before any drive was started"));
                }
                syncs += 1;
                sync_times.extend(f.time_s);
            }
            id if id == host_heartbeat => {
                heartbeats += 1;
                heartbeat_times.extend(f.time_s);
            }
            id if id > SDO_REQUEST_BASE && id <= SDO_REQUEST_BASE + 0x7F => {
                let n = (id - SDO_REQUEST_BASE) as u8;
                if let Some(i) = nodes.iter().position(|&x| x == n) {
                    if !reset[i] {
                        return Err(at(&format!(
                            "SDO to node {n} before its communication was reset"
                        )));
                    }
                    if started[i] {
                        return Err(at(&format!("SDO to node {n} after it was started")));
                    }
                }
            }
            _ => {}
        }
    }
    let heartbeat_intervals = intervals(&heartbeat_times);
    Ok(HostTrace {
        syncs,
        sync_median_period_s: median(intervals(&sync_times)),
        heartbeats,
        heartbeat_min_period_s: heartbeat_intervals.iter().copied().reduce(f64::min),
        heartbeat_median_period_s: median(heartbeat_intervals),
        started: ever_started,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::canopen::trace::parse_candump;

    const GOOD: &str = "\
(0.000000) vcan0 000#8201
(0.001000) vcan0 701#00
(0.002000) vcan0 601#4000100000000000
(0.003000) vcan0 581#4300100092010200
(0.004000) vcan0 77F#05
(0.004100) vcan0 000#0101
(0.005000) vcan0 080#
(0.006000) vcan0 080#
(0.007000) vcan0 080#
(0.014000) vcan0 77F#05
(0.024000) vcan0 77F#05
";

    #[test]
    fn a_start_up_in_order_gives_its_figures() {
        let t = check_host_trace(&parse_candump(GOOD).unwrap(), &[1], 0x7F).unwrap();
        assert_eq!((t.syncs, t.heartbeats, t.started.clone()), (3, 3, vec![1]));
        assert!((t.sync_median_period_s.unwrap() - 0.001).abs() < 1e-9);
        assert!((t.heartbeat_median_period_s.unwrap() - 0.010).abs() < 1e-9);
    }

    #[test]
    fn an_sdo_after_the_start_or_before_the_reset_is_named_with_its_line() {
        let late = format!("{GOOD}(0.030000) vcan0 601#2B17100000000000\n");
        let e = check_host_trace(&parse_candump(&late).unwrap(), &[1], 0x7F).unwrap_err();
        assert_eq!(e, "trace line 12: SDO to node 1 after it was started");
        let early = GOOD.replacen("(0.000000) vcan0 000#8201\n", "", 1);
        let e = check_host_trace(&parse_candump(&early).unwrap(), &[1], 0x7F).unwrap_err();
        assert!(e.contains("before its communication was reset"), "{e}");
        let sync_first = format!("(0.0) vcan0 080#\n{GOOD}");
        let e = check_host_trace(&parse_candump(&sync_first).unwrap(), &[1], 0x7F).unwrap_err();
        assert!(e.contains("SYNC sent before"), "{e}");
    }
}
