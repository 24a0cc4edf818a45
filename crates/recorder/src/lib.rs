//! # recorder
//!
//! Runs logged to MCAP: one channel per signal group (`/telemetry`, `/truth`) plus a 1 kHz
//! min/max/mean `/overview`, ROS 2 message schemas in CDR that Foxglove plots directly, a
//! `run` metadata record (resolved config, seed, epoch), an `environment` one (what differs
//! between runs of the same seed) and an `end` one (how the run ended), the run's input files
//! as attachments, whole-chunk zstd compression with message indexes. Writing happens on its
//! own thread behind a preallocated ring, so the servo tick never encodes or does I/O; reading
//! streams in constant memory, checks CRCs and recovers unfinished files.

#[macro_use]
pub mod frame;
mod compressors;
mod error;
pub mod export;
mod fields;
pub mod index;
pub mod mcap_file;
mod mcap_format;
mod mcap_mark;
pub mod overview;
mod placement;
pub mod reader;
mod room;
mod syncer;
mod verify;
pub mod writer;

pub use error::{Kept, RecordError};
pub use frame::{Frame, Message, TelemetryRecord, TruthRecord};
pub use index::visit_indexed;
pub use overview::{Overview, OverviewBin, Signals, OVERVIEW_PERIOD_NS};
pub use placement::{
    check_target, create_private, partial_path, partial_path_of, publish, Overwrite,
};
pub use reader::{
    fingerprint, read, stream, BadRecord, FileState, ReadError, ReadReport, Recording, Visit,
    ENVIRONMENT_RECORDS,
};
pub use writer::{
    first_file, first_part_of, part_path, Input, RecordOptions, RecordStats, Recorder, WhenFull,
    CHUNK_SPAN_NS, DEFAULT_EPOCH_NS, EPOCH_KEY, EVERY_KEY, FIRST_TICK_KEY, NEXT_PART_KEY, PART_KEY,
    PART_TICKS_KEY, RECORDED_TICKS_KEY, SPLIT_REASON, SYNC_INTERVAL, TELEMETRY_KEY,
    TELEMETRY_READING_USED, WRITE_FAILED_KEY,
};
