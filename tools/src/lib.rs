//! # videt-tools — the `videt` tool
//!
//! The technician's and researcher's subcommands ([`tool`]): configuration checks, calibration,
//! wire replacement through the service, session logs and their replay, the haptic bench, the
//! soak, plots, the designer's analysis and the paper's experiments. Uses every layer below;
//! nothing uses it but the `videt` binary.
#![warn(missing_docs)]

pub mod cli;
pub mod felt;
pub mod felt_surface;
pub mod haptic_bench;
pub mod manual;
pub mod plot_data;
pub mod plotting;
pub mod replay;
pub mod tool;
