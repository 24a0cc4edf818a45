//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p runner --test integration MODULE::`.

mod example_configs;
mod fuzz_inputs;
mod no_alloc;
mod protection;
mod servo_loop;
mod stall;
mod telemetry;
mod toolpath;
