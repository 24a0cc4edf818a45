//! # recorder
//!
//! Runs logged to MCAP: one channel per signal group (`/telemetry`, `/truth`), ROS 2 message
//! schemas in CDR that Foxglove plots directly, a `run` metadata record (resolved config,
//! version, seed), zstd-compressed chunks. Writing happens on its own thread behind a
//! preallocated ring, so the servo tick never encodes or does I/O.

pub mod frame;
pub mod reader;
pub mod writer;

pub use frame::{Frame, Telemetry, Truth};
pub use reader::{read, ReadError, Recording};
pub use writer::{Chunks, RecordError, RecordStats, Recorder, WhenFull};
