//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p servo-cli --test integration MODULE::`.

mod common;
mod damage;
mod end_to_end;
mod frf_transport;
mod hil;
mod hil_control;
mod hil_deploy;
mod input_paths;
mod latency;
mod provenance;
mod recordings;
mod replay;
mod spectrum;
mod study;
mod view_boundary;
mod workflow_daq;
