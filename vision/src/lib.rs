//! placeholder

pub mod calib;
pub mod rectify;
pub mod surface;
