//! Validation of a parsed configuration: every field against its allowed range, the GPIO
//! lines and converter settings, the colour and auto-initialization settings.

use crate::*;

/// Check that `value` lies in `[lo, hi]` (and is finite), naming `field` otherwise.
fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), ConfigError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            field: field.to_string(),
            value: value.to_string(),
            allowed: format!("in [{lo}, {hi}]"),
        })
    }
}

impl Config {
    /// Check every value against its allowed range.
    pub fn validate(&self) -> Result<(), ConfigError> {
        if !RIG_DEVICES.contains(&self.rig.device.as_str()) {
            return Err(ConfigError::Invalid {
                field: "rig.device".into(),
                value: self.rig.device.clone(),
                allowed: format!("one of {}", RIG_DEVICES.join(", ")),
            });
        }
        for (i, g) in self.rig.guides_m.iter().enumerate() {
            for (axis, v) in ["x", "y"].iter().zip(g) {
                in_range(&format!("rig.guides_m[{i}].{axis}"), *v, -2.0, 2.0)?;
            }
        }
        for (i, x) in self.rig.planar_guides_x_m.iter().enumerate() {
            in_range(&format!("rig.planar_guides_x_m[{i}]"), *x, -2.0, 2.0)?;
        }
        let [x0, x1] = self.rig.planar_guides_x_m;
        if (x1 - x0).abs() < 0.01 {
            return Err(ConfigError::Invalid {
                field: "rig.planar_guides_x_m".into(),
                value: format!("[{x0}, {x1}]"),
                allowed: "two guides at least 0.01 m apart".into(),
            });
        }
        for (axis, v) in ["x", "y", "z"].iter().zip(&self.rig.polar_guide_m) {
            in_range(&format!("rig.polar_guide_m.{axis}"), *v, -2.0, 2.0)?;
        }
        for (i, g) in self.rig.spidar_guides_m.iter().enumerate() {
            for (axis, v) in ["x", "y", "z"].iter().zip(g) {
                in_range(&format!("rig.spidar_guides_m[{i}].{axis}"), *v, -2.0, 2.0)?;
            }
        }
        let t = &self.transmission;
        if !(1..=1_000_000).contains(&t.counts_per_motor_rev) {
            return Err(ConfigError::Invalid {
                field: "transmission.counts_per_motor_rev".into(),
                value: t.counts_per_motor_rev.to_string(),
                allowed: "in [1, 1000000]".into(),
            });
        }
        in_range("transmission.gear_ratio", t.gear_ratio, 1.0, 1000.0)?;
        in_range(
            "transmission.pulley_radius_m",
            t.pulley_radius_m,
            0.001,
            0.2,
        )?;
        in_range("transmission.efficiency", t.efficiency, 0.05, 1.0)?;
        in_range("transmission.wire_ea_n", t.wire_ea_n, 500.0, 1.0e6)?;
        in_range("transmission.inside_wire_m", t.inside_wire_m, 0.0, 2.0)?;
        let c = &self.control;
        in_range("control.rate_hz", c.rate_hz as f64, 1000.0, 10000.0)?;
        in_range(
            "control.stiffness_n_per_m",
            c.stiffness_n_per_m,
            0.0,
            20000.0,
        )?;
        in_range("control.damping_n_s_per_m", c.damping_n_s_per_m, 0.0, 100.0)?;
        if !["P1", "P2", "F1", "F2", "QP"].contains(&c.algorithm.as_str()) {
            return Err(ConfigError::Invalid {
                field: "control.algorithm".into(),
                value: c.algorithm.clone(),
                allowed: "one of P1, P2, F1, F2, QP".into(),
            });
        }
        in_range("control.t_max_n", c.t_max_n, 0.5, 15.0)?;
        in_range("control.t_min_n", c.t_min_n, 0.05, c.t_max_n)?;
        in_range("control.field_n", c.field_n, 0.0, c.t_max_n)?;
        in_range(
            "control.free_space_field_n",
            c.free_space_field_n,
            0.0,
            c.t_max_n,
        )?;
        in_range(
            "control.max_wire_speed_m_s",
            c.max_wire_speed_m_s,
            0.01,
            0.8,
        )?;
        in_range(
            "control.tension_kp_nm_per_n",
            c.tension_kp_nm_per_n,
            0.0,
            0.1,
        )?;
        in_range(
            "control.tension_ki_nm_per_n_s",
            c.tension_ki_nm_per_n_s,
            0.0,
            10.0,
        )?;
        in_range(
            "control.tension_integral_speed_gate_m_s",
            c.tension_integral_speed_gate_m_s,
            0.0,
            c.max_wire_speed_m_s,
        )?;
        in_range("control.ramp_down_s", c.ramp_down_s, 0.0, 10.0)?;
        in_range(
            "control.slack_takeup_speed_m_s",
            c.slack_takeup_speed_m_s,
            0.01,
            0.5 * c.max_wire_speed_m_s,
        )?;
        in_range(
            "control.speed_gain_nm_s_per_m",
            c.speed_gain_nm_s_per_m,
            0.0,
            1.0,
        )?;
        in_range(
            "realtime.control_priority",
            self.realtime.control_priority as f64,
            1.0,
            99.0,
        )?;
        self.validate_autoinit()?;
        self.validate_commission()?;
        self.validate_colour()?;
        for (field, path) in [
            ("files.calibration", &self.files.calibration),
            ("files.motors_lock", &self.files.motors_lock),
        ] {
            if path.is_empty() || path.ends_with('/') {
                return Err(ConfigError::Invalid {
                    field: field.into(),
                    value: format!("{path:?}"),
                    allowed: "a file path".into(),
                });
            }
        }
        in_range(
            "realtime.control_cpu",
            self.realtime.control_cpu as f64,
            -1.0,
            1023.0,
        )?;
        let rt = &self.realtime;
        let vision_max = (f64::from(rt.control_priority) - 1.0).max(0.0);
        in_range(
            "realtime.vision_priority",
            f64::from(rt.vision_priority),
            0.0,
            vision_max,
        )?;
        in_range(
            "realtime.cpu_wakeup_latency_us",
            f64::from(rt.cpu_wakeup_latency_us),
            -1.0,
            10000.0,
        )?;
        in_range(
            "realtime.max_consecutive_overruns",
            f64::from(rt.max_consecutive_overruns),
            1.0,
            1_000_000.0,
        )?;
        let d = &self.drives;
        if d.can_interface.is_empty() || d.can_interface.len() > 15 {
            return Err(ConfigError::Invalid {
                field: "drives.can_interface".into(),
                value: d.can_interface.clone(),
                allowed: "an interface name of 1 to 15 characters".into(),
            });
        }
        for (i, id) in d.node_ids.iter().enumerate() {
            in_range(&format!("drives.node_ids[{i}]"), f64::from(*id), 1.0, 127.0)?;
        }
        if d.node_ids[0] == d.node_ids[1]
            || d.node_ids[0] == d.node_ids[2]
            || d.node_ids[1] == d.node_ids[2]
        {
            return Err(ConfigError::Invalid {
                field: "drives.node_ids".into(),
                value: format!("{:?}", d.node_ids),
                allowed: "three different node ids".into(),
            });
        }
        in_range("drives.rated_torque_nm", d.rated_torque_nm, 1e-4, 10.0)?;
        in_range(
            "drives.heartbeat_ms",
            f64::from(d.heartbeat_ms),
            1.0,
            1000.0,
        )?;
        let hb_min = 2.0 * f64::from(d.heartbeat_ms);
        in_range(
            "drives.heartbeat_timeout_ms",
            f64::from(d.heartbeat_timeout_ms),
            hb_min,
            10000.0,
        )?;
        in_range(
            "drives.host_silence_timeout_ms",
            f64::from(d.host_silence_timeout_ms),
            20.0,
            10000.0,
        )?;
        in_range(
            "drives.sdo_timeout_ms",
            f64::from(d.sdo_timeout_ms),
            10.0,
            5000.0,
        )?;
        in_range(
            "drives.max_missed_cycles",
            f64::from(d.max_missed_cycles),
            0.0,
            100.0,
        )?;
        in_range("drives.pdo_wait_fraction", d.pdo_wait_fraction, 0.1, 0.95)?;
        in_range(
            "drives.power_timeout_ms",
            f64::from(d.power_timeout_ms),
            10.0,
            10000.0,
        )?;
        if !CAN_BITRATES.contains(&d.bitrate) {
            return Err(ConfigError::Invalid {
                field: "drives.bitrate".into(),
                value: d.bitrate.to_string(),
                allowed: format!("one of {CAN_BITRATES:?} (bit/s)"),
            });
        }
        in_range("drives.max_bus_load", d.max_bus_load, 0.1, 0.95)?;
        self.validate_drive_units()?;
        in_range(
            "sensors.stale_after_ms",
            f64::from(self.sensors.stale_after_ms),
            1.0,
            1000.0,
        )?;
        self.validate_sensors()?;
        in_range(
            "vision.surface_max_age_s",
            self.vision.surface_max_age_s,
            0.05,
            60.0,
        )?;
        in_range(
            "vision.surface_fade_s",
            self.vision.surface_fade_s,
            0.0,
            10.0,
        )?;
        if self.vision.stereo_calibration.is_empty() {
            return Err(ConfigError::Invalid {
                field: "vision.stereo_calibration".into(),
                value: String::new(),
                allowed: "a file path".into(),
            });
        }
        in_range(
            "vision.rebuild_period_s",
            self.vision.rebuild_period_s,
            0.02,
            10.0,
        )?;
        in_range(
            "vision.full_refresh_s",
            self.vision.full_refresh_s,
            0.02,
            3600.0,
        )?;
        in_range(
            "vision.max_disparity_px",
            self.vision.max_disparity_px,
            1.0,
            1000.0,
        )?;
        in_range(
            "vision.min_match_confidence",
            self.vision.min_match_confidence,
            0.0,
            1.0,
        )?;
        let spacing = self.vision.patch_spacing_px;
        if !(spacing == 0 || crate::PATCH_SPACING_RANGE_PX.contains(&spacing)) {
            return Err(ConfigError::Invalid {
                field: "vision.patch_spacing_px".into(),
                value: spacing.to_string(),
                allowed: crate::PATCH_SPACING_ALLOWED.into(),
            });
        }
        in_range(
            "vision.pair_tolerance_ms",
            self.vision.pair_tolerance_ms,
            0.1,
            100.0,
        )?;
        in_range(
            "vision.frame_rate_hz",
            f64::from(self.vision.frame_rate_hz),
            1.0,
            240.0,
        )?;
        in_range(
            "telemetry.ring_records",
            f64::from(self.telemetry.ring_records),
            64.0,
            4_194_304.0,
        )?;
        in_range(
            "telemetry.max_total_mb",
            self.telemetry.max_total_mb as f64,
            16.0,
            10_000_000.0,
        )?;
        in_range(
            "telemetry.max_age_days",
            f64::from(self.telemetry.max_age_days),
            1.0,
            3650.0,
        )?;
        in_range(
            "telemetry.min_free_mb",
            self.telemetry.min_free_mb as f64,
            0.0,
            10_000_000.0,
        )?;
        if self.socket.path.is_empty() {
            return Err(ConfigError::Invalid {
                field: "socket.path".into(),
                value: String::new(),
                allowed: "a file path".into(),
            });
        }
        in_range(
            "socket.max_request_bytes",
            f64::from(self.socket.max_request_bytes),
            64.0,
            1_048_576.0,
        )?;
        in_range(
            "socket.client_timeout_ms",
            f64::from(self.socket.client_timeout_ms),
            10.0,
            600_000.0,
        )?;
        self.live.host_port()?;
        in_range("live.rate_hz", self.live.rate_hz, 1.0, 120.0)?;
        in_range(
            "live.client_backlog",
            f64::from(self.live.client_backlog),
            8.0,
            65_536.0,
        )?;
        Ok(())
    }
}

impl Config {
    /// The GPIO lines and converter settings of `[sensors]`: every line in use is distinct, and
    /// each converter has a usable device and a plausible nominal scale.
    fn validate_sensors(&self) -> Result<(), ConfigError> {
        let s = &self.sensors;
        if s.gpio_chip.is_empty() {
            return Err(ConfigError::Invalid {
                field: "sensors.gpio_chip".into(),
                value: String::new(),
                allowed: "a GPIO character device path".into(),
            });
        }
        let mut lines: Vec<(String, u32)> = vec![("sensors.estop_line".into(), s.estop_line)];
        let mut named = |field: &str, values: &[u32; 3]| {
            for (i, v) in values.iter().enumerate() {
                lines.push((format!("{field}[{i}]"), *v));
            }
        };
        named("sensors.vibrotactor_lines", &s.vibrotactor_lines);
        let rates: &[u32] = match (s.adc, s.ads1220_mode) {
            (TensionAdc::Hx711, _) => &HX711_SPS,
            (TensionAdc::Ads1220, Ads1220Mode::Normal) => &ADS1220_NORMAL_SPS,
            (TensionAdc::Ads1220, Ads1220Mode::Turbo) => &ADS1220_TURBO_SPS,
            (TensionAdc::Drive, _) => &[],
        };
        if !rates.is_empty() && !rates.contains(&s.sample_rate_sps) {
            return Err(ConfigError::Invalid {
                field: "sensors.sample_rate_sps".into(),
                value: s.sample_rate_sps.to_string(),
                allowed: format!(
                    "one of {rates:?} for this converter (sensors.adc, sensors.ads1220_mode)"
                ),
            });
        }
        match s.adc {
            TensionAdc::Ads1220 => named("sensors.drdy_lines", &s.drdy_lines),
            TensionAdc::Hx711 => {
                named("sensors.hx711_clock_lines", &s.hx711_clock_lines);
                named("sensors.hx711_data_lines", &s.hx711_data_lines);
            }
            TensionAdc::Drive => {}
        }
        for (k, (field, line)) in lines.iter().enumerate() {
            if let Some((other, _)) = lines[..k].iter().find(|(_, l)| l == line) {
                return Err(ConfigError::Invalid {
                    field: field.clone(),
                    value: line.to_string(),
                    allowed: format!("a GPIO line not used already (it is {other})"),
                });
            }
        }
        if s.adc == TensionAdc::Drive {
            if !(0x2000..=0x9FFF).contains(&s.drive_analog_index) {
                return Err(ConfigError::Invalid {
                    field: "sensors.drive_analog_index".into(),
                    value: format!("{:#06x}", s.drive_analog_index),
                    allowed: "in [0x2000, 0x9fff] (a manufacturer or device-profile object)".into(),
                });
            }
            let sub = s.drive_analog_subindex;
            if sub == 0xFF || (s.drive_analog_index == 0x6401 && sub == 0) {
                return Err(ConfigError::Invalid {
                    field: "sensors.drive_analog_subindex".into(),
                    value: sub.to_string(),
                    allowed: "in [0, 254], and in [1, 254] for 0x6401 (its subindex 0 is the \
                              number of inputs)"
                        .into(),
                });
            }
        }
        if s.adc == TensionAdc::Ads1220 {
            for (i, path) in s.spi_devices.iter().enumerate() {
                if path.is_empty() || s.spi_devices[..i].contains(path) {
                    return Err(ConfigError::Invalid {
                        field: format!("sensors.spi_devices[{i}]"),
                        value: format!("{path:?}"),
                        allowed: "a spidev device path, one per wire".into(),
                    });
                }
            }
        }
        // A drive's analog input is a 16-bit value in the drive's own unit (often mV): its
        // counts are coarser than a 24-bit converter's.
        let (counts, scales, allowed) = if s.adc == TensionAdc::Drive {
            (
                (-32_768.0, 32_767.0),
                1e-6..=1.0,
                "between 1e-6 and 1 in magnitude for adc = \"drive\" (negative for an inverted \
                 amplifier)",
            )
        } else {
            (
                (-8_388_608.0, 8_388_607.0),
                1e-9..=1e-2,
                "between 1e-9 and 1e-2 in magnitude (negative for an inverted bridge)",
            )
        };
        for i in 0..3 {
            in_range(
                &format!("sensors.zero_counts[{i}]"),
                f64::from(s.zero_counts[i]),
                counts.0,
                counts.1,
            )?;
            let scale = s.newtons_per_count[i];
            if !(scale.is_finite() && scales.contains(&scale.abs())) {
                return Err(ConfigError::Invalid {
                    field: format!("sensors.newtons_per_count[{i}]"),
                    value: scale.to_string(),
                    allowed: allowed.into(),
                });
            }
        }
        Ok(())
    }

    fn validate_colour(&self) -> Result<(), ConfigError> {
        let c = &self.colour;
        if !(1..=31).contains(&c.window_px) || c.window_px.is_multiple_of(2) {
            return Err(ConfigError::Invalid {
                field: "colour.window_px".into(),
                value: c.window_px.to_string(),
                allowed: "odd, in [1, 31]".into(),
            });
        }
        if c.space == ColourSpaceName::Chromaticity {
            in_range("colour.black_level", c.black_level, 0.0, 254.0)?;
            in_range(
                "colour.white_level",
                c.white_level,
                c.black_level + 1.0,
                255.0,
            )?;
        }
        in_range("colour.low_mid", c.low_mid, 1.0, 254.0)?;
        in_range("colour.mid_high", c.mid_high, c.low_mid + 1.0, 255.0)?;
        let band = (c.mid_high - c.low_mid) / 2.0;
        if !(c.hysteresis >= 0.0 && c.hysteresis < band) {
            return Err(ConfigError::Invalid {
                field: "colour.hysteresis".into(),
                value: c.hysteresis.to_string(),
                allowed: format!(
                    "at least 0 and below half the gap between colour.low_mid and colour.mid_high ({band})"
                ),
            });
        }
        in_range("colour.frequency_hz", c.frequency_hz, 1.0, 1000.0)?;
        let mut lowest = 0.0;
        for (i, &duty) in c.duty.iter().enumerate() {
            in_range(&format!("colour.duty[{i}]"), duty, lowest, 1.0)?;
            lowest = duty;
        }
        Ok(())
    }

    fn validate_commission(&self) -> Result<(), ConfigError> {
        let m = &self.commission;
        in_range(
            "commission.test_tension_n",
            m.test_tension_n,
            0.5,
            self.control.t_max_n.min(5.0),
        )?;
        in_range("commission.pull_out_m", m.pull_out_m, 0.03, 0.5)?;
        in_range("commission.max_speed_m_s", m.max_speed_m_s, 0.01, 0.2)?;
        Ok(())
    }

    fn validate_autoinit(&self) -> Result<(), ConfigError> {
        let a = &self.autoinit;
        let c = &self.control;
        in_range(
            "autoinit.wind_speed_m_s",
            a.wind_speed_m_s,
            0.005,
            c.max_wire_speed_m_s.min(0.3),
        )?;
        in_range(
            "autoinit.pay_out_tension_n",
            a.pay_out_tension_n,
            c.t_min_n,
            c.t_max_n.min(2.0),
        )?;
        in_range(
            "autoinit.wind_tension_max_n",
            a.wind_tension_max_n,
            a.pay_out_tension_n + 0.5,
            c.t_max_n,
        )?;
        in_range("autoinit.side_tolerance_m", a.side_tolerance_m, 1e-4, 0.02)?;
        in_range("autoinit.min_side_m", a.min_side_m, 0.01, 1.0)?;
        in_range("autoinit.max_length_m", a.max_length_m, 0.1, 5.0)?;
        in_range("autoinit.min_travel_m", a.min_travel_m, 0.001, 0.2)?;
        in_range("autoinit.max_wind_travel_m", a.max_wind_travel_m, 0.01, 5.0)?;
        in_range("autoinit.stage_timeout_s", a.stage_timeout_s, 1.0, 600.0)?;
        in_range(
            "autoinit.workspace_force_n",
            a.workspace_force_n,
            0.0,
            c.t_max_n,
        )?;
        in_range(
            "autoinit.workspace_max_condition",
            a.workspace_max_condition,
            1.0,
            1000.0,
        )?;
        in_range("autoinit.workspace_z_min_m", a.workspace_z_min_m, 0.01, 2.0)?;
        in_range(
            "autoinit.workspace_z_max_m",
            a.workspace_z_max_m,
            a.workspace_z_min_m,
            2.0,
        )?;
        in_range(
            "autoinit.wire_length_margin_m",
            a.wire_length_margin_m,
            0.0,
            1.0,
        )?;
        Ok(())
    }
}
