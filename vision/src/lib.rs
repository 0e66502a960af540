//! placeholder

pub mod calib;
pub mod rectify;
