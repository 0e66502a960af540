//! VIDET vision: the stereo pipeline and the bas-relief surface model.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod surface;
