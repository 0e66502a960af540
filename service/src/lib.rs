//! # videt-service — the `videtd` service
//!
//! A validated plan built from the configuration ([`plan`]) and the one builder that opens the
//! hardware or the twin, builds the control cycle and starts the threads ([`launch`]); the
//! service's threads ([`run`]), the control socket and its protocol, the procedures
//! (auto-initialization, tension calibration, wire replacement), and the vision and colour
//! threads that feed the control loop.
#![warn(missing_docs)]

pub mod camera_feed;
pub mod camera_relief;
pub mod cli;
pub mod colour_thread;
pub mod drive_report;
pub mod init;
pub mod launch;
pub mod logging;
pub mod plan;
pub mod procedure_stream;
pub mod relief_feed;
pub mod relief_scene;
pub mod run;
pub mod scene_feed;
pub mod service_hardware;
pub mod socket;
pub mod stereo_relief;
