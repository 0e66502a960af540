//! # videt-experiments — the paper's experiments on the digital twin
//!
//! Section 6 of the VIDET paper reports three explorations of virtual surfaces; this crate runs
//! each on the digital twin (`videt-sim`) with the real control step (`videt-control`), closing
//! the loop through the HAL at 1 kHz on a simulated clock, and draws the figures as the paper
//! does:
//!
//! - [`fig18()`]: the planar two-wire prototype follows a polygonal profile with algorithm P1,
//!   some of whose normals lie outside region A;
//! - [`fig22()`]: the planar prototype explores a surface whose normal lies in region C, felt
//!   thanks to a force field (F1, `|f_c| = 2 N`), against the same run with P1 and no field;
//! - [`fig23()`]: the one-wire device explores a polygonal contour.
//!
//! [`write_figures`] runs all three and writes the PNG figures and a summary.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod closed_loop;
pub mod fig18;
pub mod fig22;
pub mod fig23;
pub mod figures;
pub mod geometry;
pub mod params;

pub use closed_loop::{run_closed_loop, LoopSettings, Run, Sample};
pub use fig18::{fig18, Fig18, Fig18Summary};
pub use fig22::{fig22, Fig22, Fig22Summary, RegionCSummary};
pub use fig23::{fig23, Fig23, Fig23Summary};
pub use figures::{write_figures, write_figures_of};
pub use params::ControlConfig;

/// Why an experiment or its figures failed.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The twin refused a HAL call.
    #[error("the twin: {0}")]
    Twin(#[from] videt_sim::TwinError),
    /// Writing a file failed.
    #[error("writing {path}: {source}")]
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The failure.
        source: std::io::Error,
    },
    /// Drawing a figure failed.
    #[error("drawing {path}: {message}")]
    Plot {
        /// The file.
        path: std::path::PathBuf,
        /// What the plotting library said.
        message: String,
    },
}
