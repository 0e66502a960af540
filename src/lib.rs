//! VIDET runtime
