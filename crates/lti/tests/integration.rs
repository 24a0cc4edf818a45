//! The crate's integration tests as one binary (one link, one run in parallel); each
//! module is one concern: `cargo test -p lti --test integration MODULE::`.

mod carex;
mod common;
mod darex;
mod deterministic_products;
mod near_boundary;
mod riccati_random;
mod schur_form;
