//! VIDET in the robotics ecosystem's viewers (Foxglove, PlotJuggler): a session's topics in
//! Foxglove's well-known schemas, written to MCAP from a session log, or served live over the
//! Foxglove WebSocket protocol.

mod checked_writer;
pub mod live;
pub mod mcap_export;
mod mcap_session;
pub mod topics;
pub mod ws_server;
