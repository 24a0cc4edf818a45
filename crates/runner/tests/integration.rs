//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p runner --test integration MODULE::`.

mod example_configs;
mod fuzz_inputs;
mod measured_design;
mod no_alloc;
mod plan_loop;
mod protection;
mod recorded_deployment;
mod stall;
mod telemetry;
