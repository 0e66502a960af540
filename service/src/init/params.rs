//! The procedure's settings from the configuration.

use videt_config::Config;
use videt_control::autoinit::{ProcedureParams, WorkspaceSpec};

use videt_runtime::setup;

/// Procedure settings: `[autoinit]` for the procedure, `[control]` for the device limits.
pub fn procedure_params(config: &Config) -> ProcedureParams {
    let a = &config.autoinit;
    let c = &config.control;
    let tr = setup::transmission(config);
    ProcedureParams {
        metres_per_count: tr.metres_per_count(),
        pay_out_tension_n: a.pay_out_tension_n,
        wind_tension_max_n: a.wind_tension_max_n,
        wind_speed_m_s: a.wind_speed_m_s,
        speed_kp_n_per_m_s: 20.0,
        speed_ki_n_per_m: 200.0,
        settle_s: 0.3,
        stop_hold_s: 0.2,
        measure_s: 0.3,
        stage_timeout_s: a.stage_timeout_s,
        min_travel_m: a.min_travel_m,
        max_wind_travel_m: a.max_wind_travel_m,
        min_side_m: a.min_side_m,
        max_length_m: a.max_length_m,
        side_tolerance_m: a.side_tolerance_m,
        max_tension_n: c.t_max_n,
        over_tension_s: 0.005,
        // The procedure winds at `wind_speed_m_s`; anything much faster is a runaway.
        max_speed_m_s: c.max_wire_speed_m_s,
    }
}

/// The workspace definition of `[autoinit]`.
pub fn workspace_spec(config: &Config) -> WorkspaceSpec {
    let a = &config.autoinit;
    WorkspaceSpec {
        force_n: a.workspace_force_n,
        t_min_n: config.control.t_min_n,
        t_max_n: config.control.t_max_n,
        max_condition: a.workspace_max_condition,
        z_min_m: a.workspace_z_min_m,
        z_max_m: a.workspace_z_max_m,
        step_m: 0.01,
    }
}
