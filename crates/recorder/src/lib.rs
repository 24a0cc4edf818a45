//! # recorder
//!
//! Runs logged to MCAP: one channel per signal group (`/telemetry`, `/truth`), ROS 2 message
//! schemas in CDR that Foxglove plots directly, a `run` metadata record (resolved config,
//! version, seed) and an `end` one (how the run ended), the run's input files as attachments,
//! zstd-compressed chunks with message indexes. Writing happens on its own thread behind a
//! preallocated ring, so the servo tick never encodes or does I/O.

pub mod frame;
pub mod reader;
pub mod writer;

pub use frame::{Frame, Telemetry, Truth};
pub use reader::{read, stream, FileState, ReadError, ReadReport, Recording, Visit};
pub use writer::{
    check_target, partial_path, Chunks, Input, Overwrite, RecordError, RecordOptions, RecordStats,
    Recorder, WhenFull, CHUNK_BYTES,
};
