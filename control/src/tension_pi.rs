//! Tension control of each wire: PI on the measured tension with a static feed-forward of the
//! set-point, a wire-speed limit, and slack take-up.
//!
//! A wire that lost its tension (the finger moved towards the guide faster than the motor wound
//! in, or the thimble was let go) is not wound in at full torque, which would make the wire snap
//! taut with a tension spike: below `slack_tension_n` the wire is wound in under speed control
//! at `takeup_speed_m_s` until it pulls again. While pulling, winding faster than
//! `max_winding_speed_m_s` is braked.

/// Gains and limits of the tension loop (same for every wire).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionPiGains {
    /// Feed-forward: motor torque per newton of tension, N·m/N (pulley radius / gear ratio).
    pub feedforward_nm_per_n: f64,
    /// Proportional gain, N·m per newton of tension error.
    pub kp_nm_per_n: f64,
    /// Integral gain, N·m per newton-second of tension error.
    pub ki_nm_per_n_s: f64,
    /// Largest motor torque magnitude commanded, N·m.
    pub torque_limit_nm: f64,
    /// Speed-loop gain for take-up and the speed limit, N·m per m/s of wire speed.
    pub speed_gain_nm_s_per_m: f64,
    /// Below this measured tension a wire is slack and is taken up, newtons.
    pub slack_tension_n: f64,
    /// Winding speed of slack take-up, m/s.
    pub takeup_speed_m_s: f64,
    /// Winding faster than this is braked, m/s.
    pub max_winding_speed_m_s: f64,
    /// The integral learns while the wire is nearly still: its rate is scaled by
    /// `1 - |speed| / gate` (none at or above `gate`), m/s. Infinite: it learns at any speed.
    pub integral_speed_gate_m_s: f64,
}

impl TensionPiGains {
    /// Gains with only the PI part (no take-up, no speed limit): `speed_gain` 0.
    pub fn pi_only(
        feedforward_nm_per_n: f64,
        kp_nm_per_n: f64,
        ki_nm_per_n_s: f64,
        torque_limit_nm: f64,
    ) -> Self {
        TensionPiGains {
            feedforward_nm_per_n,
            kp_nm_per_n,
            ki_nm_per_n_s,
            torque_limit_nm,
            speed_gain_nm_s_per_m: 0.0,
            slack_tension_n: f64::NEG_INFINITY,
            takeup_speed_m_s: 0.0,
            max_winding_speed_m_s: f64::INFINITY,
            integral_speed_gate_m_s: f64::INFINITY,
        }
    }
}

/// Alignment with the contact normal of the wire pulling most along it, `max_i n·u_i`, from which
/// on the tension loop keeps its whole proportional gain in contact (see [`contact_gain_share`]).
pub const FULL_GAIN_ALIGNMENT: f64 = 0.8;

/// The least share of the proportional gain the tension loop keeps in contact.
pub const MIN_GAIN_SHARE: f64 = 0.7;

/// Contact force over which the contact's gain share is blended in, newtons.
pub const GAIN_SHARE_BLEND_N: f64 = 1.0;

/// The share of the tension loop's proportional gain to use in contact, from the alignment
/// `alignment` = `max_i n·u_i` of the wire pulling most along the contact normal `n` and the
/// contact force asked (newtons).
///
/// Facing the frame (the paper's region A) some wire pulls nearly along the normal and the
/// whole gain is kept. On a side wall (region B) the wire that renders the normal force pulls
/// at a steep angle to it, so its tension pulls the finger across the normal too, and the
/// idle wires sit at the floor; with the drives' one-period command delay the whole gain makes
/// such a wall oscillate at about half the stiffness the frame's wall holds (`videt
/// bench-haptic`, docs/haptic-bench.md). The share falls in proportion to the alignment below
/// [`FULL_GAIN_ALIGNMENT`], to no less than [`MIN_GAIN_SHARE`], and is blended in over the
/// first [`GAIN_SHARE_BLEND_N`] of contact force, so it is continuous at the contact's onset
/// and in the pose. A non-finite input keeps the whole gain.
pub fn contact_gain_share(alignment: f64, contact_force_n: f64) -> f64 {
    if !(alignment.is_finite() && contact_force_n.is_finite()) {
        return 1.0;
    }
    let scheduled = (alignment / FULL_GAIN_ALIGNMENT).clamp(MIN_GAIN_SHARE, 1.0);
    let blend = (contact_force_n / GAIN_SHARE_BLEND_N).clamp(0.0, 1.0);
    1.0 - blend * (1.0 - scheduled)
}

/// Per-wire PI tension controller with anti-windup (conditional integration at the torque
/// limit), slack take-up and a winding-speed limit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TensionPi<const N: usize> {
    gains: TensionPiGains,
    integral_nm: [f64; N],
}

impl<const N: usize> TensionPi<N> {
    /// A controller with zero integral state.
    pub fn new(gains: TensionPiGains) -> TensionPi<N> {
        TensionPi {
            gains,
            integral_nm: [0.0; N],
        }
    }

    /// The gains.
    pub fn gains(&self) -> &TensionPiGains {
        &self.gains
    }

    /// Forget the integral state (after a fault or when the drives were off).
    pub fn reset(&mut self) {
        self.integral_nm = [0.0; N];
    }

    /// One update without speed information (speeds taken as zero): motor torques (N·m,
    /// positive = winding) into `torque_nm` for the set-points and measured tensions (N).
    pub fn update(
        &mut self,
        setpoint_n: &[f64; N],
        measured_n: &[f64; N],
        dt_s: f64,
        torque_nm: &mut [f64; N],
    ) {
        self.update_with_speed(setpoint_n, measured_n, &[0.0; N], dt_s, torque_nm);
    }

    /// One update: motor torques (N·m, positive = winding) into `torque_nm` for the set-points
    /// and measured tensions (N) and the wires' winding speeds (m/s, positive = winding in), over
    /// a period `dt_s` seconds. Non-finite measurements are treated as zero error (the safety
    /// layer decides what a broken sensor means).
    pub fn update_with_speed(
        &mut self,
        setpoint_n: &[f64; N],
        measured_n: &[f64; N],
        winding_speed_m_s: &[f64; N],
        dt_s: f64,
        torque_nm: &mut [f64; N],
    ) {
        self.update_with_gain_share(
            setpoint_n,
            measured_n,
            winding_speed_m_s,
            1.0,
            dt_s,
            torque_nm,
        );
    }

    /// [`update_with_speed`](Self::update_with_speed) with the proportional gain scaled by
    /// `kp_share` (in `[0, 1]`; [`contact_gain_share`] in contact).
    pub fn update_with_gain_share(
        &mut self,
        setpoint_n: &[f64; N],
        measured_n: &[f64; N],
        winding_speed_m_s: &[f64; N],
        kp_share: f64,
        dt_s: f64,
        torque_nm: &mut [f64; N],
    ) {
        let g = &self.gains;
        let kp = g.kp_nm_per_n * kp_share.clamp(0.0, 1.0);
        for i in 0..N {
            let speed = if winding_speed_m_s[i].is_finite() {
                winding_speed_m_s[i]
            } else {
                0.0
            };
            let ff = g.feedforward_nm_per_n * setpoint_n[i];
            let slack = measured_n[i].is_finite() && measured_n[i] < g.slack_tension_n;
            let out = if slack {
                // Take up the slack at a bounded speed. A slack wire carries
                // no load: the set-point's feed-forward would only drive the free pulley past
                // the take-up speed (by feed-forward / speed gain, metres per second at high
                // set-points) and snap the wire taut. Only the slack threshold's share is fed
                // forward, so the speed loop sets the winding speed.
                let hold = g.feedforward_nm_per_n * setpoint_n[i].min(g.slack_tension_n).max(0.0);
                // The integral restarts from zero: what it learnt on the loaded wire does not
                // hold for a slack one, and the negative integral the snap of the last take-up
                // left (the tension measured late, above the set-point) would unwind the wire
                // the moment it pulls again, slackening it once more: a ratchet that sustains
                // slack-snap cycles on a converter with a filter delay.
                self.integral_nm[i] = 0.0;
                hold + g.speed_gain_nm_s_per_m * (g.takeup_speed_m_s - speed)
            } else {
                let error = if measured_n[i].is_finite() {
                    setpoint_n[i] - measured_n[i]
                } else {
                    0.0
                };
                let learning = if g.integral_speed_gate_m_s.is_finite() {
                    (1.0 - speed.abs() / g.integral_speed_gate_m_s).max(0.0)
                } else {
                    1.0
                };
                let candidate_integral =
                    self.integral_nm[i] + g.ki_nm_per_n_s * error * dt_s * learning;
                let unclamped = ff + kp * error + candidate_integral;
                let saturating =
                    unclamped.abs() > g.torque_limit_nm && unclamped.signum() == error.signum();
                if !saturating && candidate_integral.is_finite() {
                    self.integral_nm[i] =
                        candidate_integral.clamp(-g.torque_limit_nm, g.torque_limit_nm);
                }
                let overspeed = (speed - g.max_winding_speed_m_s).max(0.0);
                ff + kp * error + self.integral_nm[i] - g.speed_gain_nm_s_per_m * overspeed
            };
            torque_nm[i] = if out.is_finite() {
                out.clamp(-g.torque_limit_nm, g.torque_limit_nm)
            } else {
                0.0
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = 3;

    fn gains() -> TensionPiGains {
        TensionPiGains {
            feedforward_nm_per_n: 0.0008,
            kp_nm_per_n: 0.0005,
            ki_nm_per_n_s: 0.02,
            torque_limit_nm: 0.02,
            speed_gain_nm_s_per_m: 0.005,
            slack_tension_n: 0.15,
            takeup_speed_m_s: 0.15,
            max_winding_speed_m_s: 0.6,
            integral_speed_gate_m_s: f64::INFINITY,
        }
    }

    #[test]
    fn the_gain_share_scales_the_proportional_term_alone() {
        let sp = [2.0, 1.0, 0.5];
        let measured = [1.5, 1.2, 0.5];
        let (mut whole, mut shared, mut plain) = (
            TensionPi::<N>::new(gains()),
            TensionPi::<N>::new(gains()),
            TensionPi::<N>::new(gains()),
        );
        let (mut t_whole, mut t_shared, mut t_plain) = ([0.0; N], [0.0; N], [0.0; N]);
        for _ in 0..5 {
            whole.update_with_gain_share(&sp, &measured, &[0.0; N], 1.0, 1e-3, &mut t_whole);
            shared.update_with_gain_share(&sp, &measured, &[0.0; N], 0.7, 1e-3, &mut t_shared);
            plain.update_with_speed(&sp, &measured, &[0.0; N], 1e-3, &mut t_plain);
        }
        assert_eq!(t_whole, t_plain);
        for i in 0..N {
            let expected = 0.3 * gains().kp_nm_per_n * (sp[i] - measured[i]);
            assert!(
                ((t_whole[i] - t_shared[i]) - expected).abs() < 1e-15,
                "{t_whole:?} {t_shared:?}"
            );
        }
    }

    #[test]
    fn the_contact_gain_share_falls_with_the_alignment_and_blends_in_with_the_force() {
        // Facing the frame: the whole gain.
        assert_eq!(contact_gain_share(0.95, 5.0), 1.0);
        assert_eq!(contact_gain_share(FULL_GAIN_ALIGNMENT, 5.0), 1.0);
        // A side wall (the best wire about 56° from the normal): the least share.
        assert!((contact_gain_share(0.56, 5.0) - MIN_GAIN_SHARE).abs() < 1e-12);
        assert!((contact_gain_share(-0.3, 5.0) - MIN_GAIN_SHARE).abs() < 1e-12);
        assert!((contact_gain_share(0.72, 5.0) - 0.9).abs() < 1e-12);
        // At the contact's onset the whole gain, blended in over the first newton.
        assert_eq!(contact_gain_share(0.56, 0.0), 1.0);
        assert!(
            (contact_gain_share(0.56, 0.5) - (1.0 - 0.5 * (1.0 - MIN_GAIN_SHARE))).abs() < 1e-12
        );
        // Continuous: nearby inputs give nearby shares, everywhere on a grid.
        for a in (-10..=10).map(|k| f64::from(k) / 10.0) {
            for f in (0..=30).map(|k| f64::from(k) * 0.1) {
                let s = contact_gain_share(a, f);
                assert!((MIN_GAIN_SHARE..=1.0).contains(&s), "{a} {f} {s}");
                let near = contact_gain_share(a + 1e-7, f + 1e-7);
                assert!((near - s).abs() < 1e-5, "{a} {f}: {s} {near}");
            }
        }
        assert_eq!(contact_gain_share(f64::NAN, 1.0), 1.0);
        assert_eq!(contact_gain_share(0.5, f64::INFINITY), 1.0);
    }

    #[test]
    fn integral_removes_a_constant_error() {
        // Plant: measured tension = 0.8 * torque / feedforward (a 20% gain loss).
        let mut pi = TensionPi::new(gains());
        let sp = [5.0; N];
        let mut measured = [0.2; N];
        let mut torque = [0.0; N];
        for _ in 0..5000 {
            pi.update(&sp, &measured, 1e-3, &mut torque);
            for i in 0..N {
                measured[i] = 0.8 * torque[i] / gains().feedforward_nm_per_n;
            }
        }
        assert!((measured[0] - 5.0).abs() < 0.01, "{measured:?}");
    }

    #[test]
    fn the_speed_gate_learns_at_rest_and_holds_what_it_learnt_in_motion() {
        let gated = TensionPiGains {
            integral_speed_gate_m_s: 0.003,
            ..gains()
        };
        let sp = [2.0; N];
        let measured = [1.0; N];
        let mut torque = [0.0; N];
        // At rest it learns as the ungated integral does.
        let mut pi = TensionPi::new(gated);
        let mut plain = TensionPi::new(gains());
        for _ in 0..10 {
            pi.update_with_speed(&sp, &measured, &[0.0; N], 1e-3, &mut torque);
            plain.update_with_speed(&sp, &measured, &[0.0; N], 1e-3, &mut torque);
        }
        assert_eq!(pi.integral_nm, plain.integral_nm);
        assert!(pi.integral_nm[0] > 0.0);
        // Half the gate's speed (either way): half the rate; at the gate and beyond: none, and
        // what was learnt stays.
        let learnt = pi.integral_nm;
        pi.update_with_speed(&sp, &measured, &[0.0015, -0.0015, 0.003], 1e-3, &mut torque);
        let step = gains().ki_nm_per_n_s * 1.0 * 1e-3;
        assert!((pi.integral_nm[0] - learnt[0] - 0.5 * step).abs() < 1e-15);
        assert!((pi.integral_nm[1] - learnt[1] - 0.5 * step).abs() < 1e-15);
        assert_eq!(pi.integral_nm[2], learnt[2]);
        let held = pi.integral_nm;
        for _ in 0..100 {
            pi.update_with_speed(&sp, &measured, &[0.05; N], 1e-3, &mut torque);
        }
        assert_eq!(pi.integral_nm, held);
    }

    #[test]
    fn output_is_limited_and_finite() {
        let mut pi = TensionPi::new(gains());
        let mut torque = [0.0; N];
        pi.update_with_speed(
            &[1e9, f64::NAN, -1e9],
            &[1.0, 1.0, f64::INFINITY],
            &[f64::NAN, 0.0, 9.0],
            1e-3,
            &mut torque,
        );
        assert!(torque.iter().all(|t| t.is_finite() && t.abs() <= 0.02));
    }

    #[test]
    fn slack_is_taken_up_at_the_takeup_speed_not_at_full_torque() {
        let g = gains();
        let mut pi = TensionPi::new(g);
        let mut torque = [0.0; N];
        // Slack, standing still: wind in with a modest torque, far below the limit.
        pi.update_with_speed(&[0.3; N], &[0.0; N], &[0.0; N], 1e-3, &mut torque);
        let hold = g.feedforward_nm_per_n * g.slack_tension_n;
        let expected = hold + g.speed_gain_nm_s_per_m * g.takeup_speed_m_s;
        assert!((torque[0] - expected).abs() < 1e-12 && torque[0] < 0.5 * g.torque_limit_nm);
        // Slack, already winding at the take-up speed: only the slack threshold's feed-forward.
        pi.update_with_speed(
            &[0.3; N],
            &[0.0; N],
            &[g.takeup_speed_m_s; N],
            1e-3,
            &mut torque,
        );
        assert!((torque[0] - hold).abs() < 1e-12);
        // Whatever the set-point, a slack wire winding faster than the take-up speed is braked:
        // the set-point's feed-forward does not run the free pulley away.
        for setpoint in [0.3, 3.0, 15.0] {
            pi.update_with_speed(
                &[setpoint; N],
                &[0.0; N],
                &[2.0 * g.takeup_speed_m_s; N],
                1e-3,
                &mut torque,
            );
            assert!(torque[0] < 0.0, "set-point {setpoint} N: {} N·m", torque[0]);
        }
        // Slack does not wind the integral up.
        for _ in 0..10_000 {
            pi.update_with_speed(&[0.3; N], &[0.0; N], &[0.0; N], 1e-3, &mut torque);
        }
        pi.update_with_speed(&[0.3; N], &[0.3; N], &[0.0; N], 1e-3, &mut torque);
        assert!(
            (torque[0] - g.feedforward_nm_per_n * 0.3).abs() < 1e-9,
            "no wound-up integral"
        );
    }

    #[test]
    fn winding_faster_than_the_limit_is_braked() {
        let g = gains();
        let mut pi = TensionPi::new(g);
        let (mut slow, mut fast) = ([0.0; N], [0.0; N]);
        pi.update_with_speed(&[2.0; N], &[1.0; N], &[0.1; N], 1e-3, &mut slow);
        pi.reset();
        pi.update_with_speed(&[2.0; N], &[1.0; N], &[1.0; N], 1e-3, &mut fast);
        assert!((slow[0] - fast[0] - g.speed_gain_nm_s_per_m * 0.4).abs() < 1e-12);
    }

    #[test]
    fn a_slack_wire_forgets_the_integral_so_a_late_spike_cannot_ratchet_it() {
        let g = gains();
        let mut pi = TensionPi::new(g);
        let mut out = [0.0; N];
        // The take-up snapped the wire taut: the converter reports a spike above the set-point
        // for a few periods, which winds the integral negative...
        for _ in 0..20 {
            pi.update(&[0.4; N], &[3.0; N], 1e-3, &mut out);
        }
        assert!(pi.integral_nm[0] < 0.0);
        // ...the wire goes slack, and is taken up...
        pi.update(&[0.4; N], &[0.0; N], 1e-3, &mut out);
        // ...and pulls again: the torque is the feed-forward and the error's, nothing left from
        // the spike that would unwind it at once.
        pi.update(&[0.4; N], &[0.2; N], 1e-3, &mut out);
        let expected =
            g.feedforward_nm_per_n * 0.4 + g.kp_nm_per_n * 0.2 + g.ki_nm_per_n_s * 0.2 * 1e-3;
        assert!(
            (out[0] - expected).abs() < 1e-12,
            "{} vs {expected}",
            out[0]
        );
        assert!(out[0] > 0.0);
    }
}
