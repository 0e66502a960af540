//! What the bench varies: how much of each sweep it runs, the tension sensors the Z-width runs
//! on, and the renderings of the wall (the tension integral's speed gate, the wires' stretch
//! correction) it compares.

use serde::Serialize;
use videt_config::{Ads1220Mode, Config, TensionAdc};

/// The bench's settings: how much of each sweep to run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BenchPlan {
    /// Polar angles of the surface normals from the frame's axis (`-z`), degrees.
    pub polar_deg: &'static [f64],
    /// Azimuths of the tilted normals, degrees.
    pub azimuth_deg: &'static [f64],
    /// Wall damping values of the Z-width sweep, N·s/m.
    pub damping_n_s_per_m: &'static [f64],
    /// Bisection steps of the Z-width search.
    pub zwidth_steps: u32,
    /// Run the Z-width for every supported tension sensor (else the configured one only).
    pub all_sensors: bool,
    /// Run the Z-width at the bus's highest rate too (else at 1 kHz only).
    pub highest_rate: bool,
    /// Pushing forces of the pop-through sweep, newtons.
    pub push_n: &'static [f64],
    /// Stiffnesses the wall's feel is measured at, N/m (the configured one is added).
    pub feel_stiffness_n_per_m: &'static [f64],
}

impl BenchPlan {
    /// The full bench (a few minutes).
    pub const FULL: BenchPlan = BenchPlan {
        polar_deg: &[0.0, 15.0, 30.0, 45.0, 60.0, 90.0, 120.0, 150.0],
        azimuth_deg: &[0.0, 90.0, 180.0, 270.0],
        damping_n_s_per_m: &[0.0, 2.0, 5.0, 10.0],
        zwidth_steps: 7,
        all_sensors: true,
        highest_rate: true,
        push_n: &[1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 20.0],
        feel_stiffness_n_per_m: &[800.0, 2000.0, 5000.0],
    };
    /// A few points of each sweep (seconds; tests).
    pub const QUICK: BenchPlan = BenchPlan {
        polar_deg: &[0.0, 45.0, 150.0],
        azimuth_deg: &[0.0],
        damping_n_s_per_m: &[5.0],
        zwidth_steps: 4,
        all_sensors: false,
        highest_rate: false,
        push_n: &[2.0, 6.0],
        feel_stiffness_n_per_m: &[],
    };
}

/// A tension sensor the bench runs the Z-width on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SensorSetup {
    /// `sensors.adc`.
    pub adc: TensionAdc,
    /// `sensors.sample_rate_sps` (0 for the drive's input).
    pub sample_rate_sps: u32,
    /// ADS1220 turbo mode.
    pub turbo: bool,
}

impl SensorSetup {
    /// The supported sensors at their fastest settings.
    pub const SUPPORTED: [SensorSetup; 4] = [
        SensorSetup {
            adc: TensionAdc::Ads1220,
            sample_rate_sps: 2000,
            turbo: true,
        },
        SensorSetup {
            adc: TensionAdc::Ads1220,
            sample_rate_sps: 330,
            turbo: false,
        },
        SensorSetup {
            adc: TensionAdc::Hx711,
            sample_rate_sps: 80,
            turbo: false,
        },
        SensorSetup {
            adc: TensionAdc::Drive,
            sample_rate_sps: 0,
            turbo: false,
        },
    ];

    /// The configured sensor.
    pub fn of(config: &Config) -> SensorSetup {
        let s = &config.sensors;
        SensorSetup {
            adc: s.adc,
            sample_rate_sps: if s.adc == TensionAdc::Drive {
                0
            } else {
                s.sample_rate_sps
            },
            turbo: s.ads1220_mode == Ads1220Mode::Turbo,
        }
    }

    /// `config` with this sensor (the loop degraded where the sensor needs it, and the staleness
    /// bound at least two conversion periods).
    pub fn apply(&self, config: &mut Config) {
        let s = &mut config.sensors;
        s.adc = self.adc;
        if self.sample_rate_sps > 0 {
            s.sample_rate_sps = self.sample_rate_sps;
            let two_periods_ms = (2000 / self.sample_rate_sps + 1) as u16;
            s.stale_after_ms = s.stale_after_ms.max(two_periods_ms);
        }
        s.ads1220_mode = if self.turbo {
            Ads1220Mode::Turbo
        } else {
            Ads1220Mode::Normal
        };
        config.control.allow_degraded_tension_loop = true;
    }

    /// A name for tables and plots.
    pub fn label(&self) -> String {
        match self.adc {
            TensionAdc::Drive => "drive input".into(),
            TensionAdc::Ads1220 if self.turbo => {
                format!("ADS1220 {} SPS turbo", self.sample_rate_sps)
            }
            TensionAdc::Ads1220 => format!("ADS1220 {} SPS", self.sample_rate_sps),
            TensionAdc::Hx711 => format!("HX711 {} SPS", self.sample_rate_sps),
        }
    }
}

/// How the wall is rendered, as far as the bench compares: the tension integral's speed gate
/// and the wires' stretch correction.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rendering {
    /// `control.tension_integral_speed_gate_m_s` (0: the integral learns at any speed).
    pub integral_gate_m_s: f64,
    /// `control.stretch_compensation`.
    pub stretch_compensation: bool,
}

impl Rendering {
    /// The rendering before the gate and the stretch correction.
    pub const BEFORE: Rendering = Rendering {
        integral_gate_m_s: 0.0,
        stretch_compensation: false,
    };

    /// The configured rendering.
    pub fn of(control: &videt_config::ControlConfig) -> Rendering {
        Rendering {
            integral_gate_m_s: control.tension_integral_speed_gate_m_s,
            stretch_compensation: control.stretch_compensation,
        }
    }

    /// `config` rendering this way.
    pub fn apply(&self, config: &mut Config) {
        config.control.tension_integral_speed_gate_m_s = self.integral_gate_m_s;
        config.control.stretch_compensation = self.stretch_compensation;
    }

    /// A name for tables and plots.
    pub fn label(&self) -> String {
        let integral = if self.integral_gate_m_s > 0.0 {
            format!("integral < {:.0} mm/s", self.integral_gate_m_s * 1e3)
        } else {
            "integral at any speed".into()
        };
        let wires = if self.stretch_compensation {
            "stretch corrected"
        } else {
            "rigid wires"
        };
        format!("{integral}, {wires}")
    }
}

/// The renderings the bench compares: before the gate and the stretch correction, and the
/// configured one when it differs.
pub fn renderings_compared(base: &Config) -> Vec<Rendering> {
    let configured = Rendering::of(&base.control);
    if configured == Rendering::BEFORE {
        vec![configured]
    } else {
        vec![Rendering::BEFORE, configured]
    }
}
