//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p daq-io --test integration MODULE::`.

mod c_header;
mod common;
mod ipc;
mod realtime;
