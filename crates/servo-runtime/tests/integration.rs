//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p servo-runtime --test integration MODULE::`.

mod deployment_file;
mod no_alloc;
mod public_api;
mod serve;
mod skipped_samples;
