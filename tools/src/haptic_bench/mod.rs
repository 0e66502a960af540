//! The haptic fidelity bench: what the wearer's finger feels, measured on the timing-faithful
//! twin (the CiA 402 drives' per-mille torque and SYNC timing, the configured strain-gauge
//! converter's rate, filter and quantization) with the real control cycle.
//!
//! - **Stiffness**: the stiffness rendered by P1 and P2 against the programmed one, over
//!   surface normals in the paper's regions A, B and C (section 5, Figs 14-15).
//! - **Z-width**: the stiffest wall rendered without sustained oscillation, against damping,
//!   per control rate and tension sensor.
//! - **Pop-through**: the penetration at the wearer's pushing force, and the force the device
//!   can hold before a wire saturates.
//!
//! Every experiment is a run of the control loop on the twin's simulated clock: deterministic
//! (the same configuration gives the same figures) and independent of the machine's load.

pub mod plots;
mod pop_through;
mod region;
pub mod rig;
mod settings;
mod stiffness;
mod wall;
pub mod wall_feel;
pub mod zwidth;

use serde::Serialize;
use videt_config::Config;
use videt_control::FeltTally;

pub use pop_through::{pop_through, PopThroughReport, PushRow, WEARER_PUSH_N};
pub use region::{region_of, Region};
pub use settings::{renderings_compared, BenchPlan, Rendering, SensorSetup};
pub use stiffness::{secant_stiffness, stiffness_sweep, StiffnessRow};
pub use wall::Equilibrium;
pub use wall_feel::{feel_sweep, FeelRow};
pub use zwidth::{
    judge_wall, judge_wall_in, zwidth, zwidth_sweep, WallVerdict, ZWidthRow, ZWidthSearch,
    ZWIDTH_CRITERION, ZWIDTH_RANGE_N_PER_M,
};

/// Everything the bench measured, with the configuration it ran on.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    /// The configuration file (or "defaults").
    pub config_origin: String,
    /// The configuration's control settings.
    pub control: videt_config::ControlConfig,
    /// The configuration's sensor settings.
    pub sensor: SensorSetup,
    /// The Z-width criterion.
    pub zwidth_criterion: String,
    /// Stiffness rows.
    pub stiffness: Vec<StiffnessRow>,
    /// Z-width rows.
    pub zwidth: Vec<ZWidthRow>,
    /// What the finger felt beyond what was asked over every stiffness and Z-width run.
    pub felt: FeltTally,
    /// The long hold and release the Z-width's stiffest walls also pass.
    pub hold_criterion: String,
    /// The wall's feel before and with the configured rendering.
    pub feel: Vec<FeelRow>,
    /// Pop-through.
    pub pop_through: PopThroughReport,
}

/// Run the whole bench.
pub fn run_bench(
    config: &Config,
    origin: &str,
    plan: &BenchPlan,
    feature_mm: f64,
) -> Result<BenchReport, String> {
    let stiffness = stiffness_sweep(config, plan)?;
    let zwidth = zwidth_sweep(config, plan)?;
    let mut felt = FeltTally::new();
    for row in &stiffness {
        felt.merge(&row.felt);
    }
    for verdict in zwidth.iter().flat_map(|row| &row.tried) {
        felt.merge(&verdict.felt);
    }
    Ok(BenchReport {
        config_origin: origin.into(),
        control: config.control.clone(),
        sensor: SensorSetup::of(config),
        zwidth_criterion: ZWIDTH_CRITERION.into(),
        stiffness,
        zwidth,
        felt,
        hold_criterion: wall_feel::HOLD_CRITERION.into(),
        feel: feel_sweep(config, plan)?,
        pop_through: pop_through(config, plan, feature_mm)?,
    })
}
