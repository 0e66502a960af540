//! # videt-colour — colour-to-touch
//!
//! Paper §6.1: the colour under the finger is approximated to three levels per channel (Low,
//! Middle, High) and presented as 75 Hz vibrations at three fingertips. This crate holds:
//!
//! - [`sample`]: the thimble's workspace point through the [`videt_control::SceneMap`] (the same
//!   mapping as the bas-relief) to a left-image pixel, and the mean or median colour of a small
//!   window there (allocation-free, scratch buffer reused);
//! - [`quantize`]: Low/Mid/High per channel with configurable thresholds and hysteresis, in plain
//!   RGB or in a brightness-normalised chromaticity space (the default, see below);
//! - [`pattern`]: the pure pattern generator (time, levels) -> on/off per vibrotactor;
//! - [`vibration_loop`]: the driver loop a thread runs at a fixed tick on an injected clock, with
//!   period-jitter statistics ([`jitter`]), quiet in the safe state and on shutdown;
//! - [`twin`]: recording vibrotactors and a simulated clock for the digital twin;
//! - [`training`]: the trainer's aid behind `videt colour` (levels at a pixel, level-colour image).
//!
//! ## Default colour space: chromaticity
//!
//! Measured on 25 hand-labelled patches of the Middlebury teddy, cones, tsukuba and venus left
//! images (`tests/real_patches.rs`, labels decided by looking at the images before computing any
//! level; 7x7 median window): plain RGB with thresholds 85/170 gets 14/25 right (56 %), the
//! chromaticity space with the same thresholds and its a-priori brightness stretch (black 32,
//! white 192) gets 17/25 (68 %). The camera
//! images are dim and shaded; plain RGB turns most colours into their "dark" variants
//! (yellow -> olive, pink -> maroon), while chromaticity keeps the hue and only uses brightness
//! to separate black, grey and white. Its remaining misses: deeply shaded surfaces (a maroon box
//! side at RGB 65/27/26 and a shadowed red smudge read as black), a dim grey-blue read as
//! `LLM`, pink read as `HLM`, and bright greens with a red share of 50 % read as yellow-green
//! `MHL`.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod host_clock;
pub mod jitter;
pub mod level;
pub mod pattern;
pub mod quantize;
pub mod reader;
pub mod sample;
pub mod training;
pub mod twin;
pub mod vibration_loop;

pub use host_clock::HostClock;
pub use jitter::PeriodJitter;
pub use level::{Level, LevelTriple};
pub use pattern::{Pattern, PatternConfig};
pub use quantize::{ColourSpace, Quantizer, QuantizerConfig};
pub use reader::{ColourReader, ColourReading};
pub use sample::{SampleError, SamplerConfig, WindowSampler, WindowStatistic};
pub use twin::{RecordingVibrotactors, SimulatedClock};
pub use vibration_loop::{VibrationInputs, VibrationLoop};
