//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p recorder --test integration MODULE::`.

mod chunk_bytes;
mod common;
mod export;
mod fuzz_reader;
mod late_attachments;
mod legacy;
mod round_trip;
mod split;
