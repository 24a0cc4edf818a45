//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p design --test integration MODULE::`.

mod h2_assumptions;
mod h2_continuous;
mod identify;
mod tune;
mod zpetc;
