//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p plant-sim --test integration MODULE::`.

mod calibration;
mod coil;
mod common;
mod model_frf;
mod no_alloc;
mod noise;
mod quantisation;
mod simulator;
