//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p servo-core --test integration MODULE::`.

mod common;
mod limits_and_faults;
mod no_alloc;
mod repetitive;
mod setpoint;
mod surfaces;
