//! Rectification maps.
