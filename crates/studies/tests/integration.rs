//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p studies --test integration MODULE::`.

mod budget;
mod budget_exact;
mod common;
mod compensation;
mod design_space;
mod frf_fit;
mod frf_practice;
mod fuzz_frf_csv;
mod identify;
mod identify_coverage;
mod intermittent;
mod machining;
mod repetitive;
mod spectrum_lost_ticks;
mod spindle_errors;
mod toolpath;
mod toolpath_demands;
mod tune;
