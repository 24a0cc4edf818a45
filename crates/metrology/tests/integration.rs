//! The crate's integration tests as one binary: `cargo test -p metrology --test integration`.

mod formats;
mod registration;
mod support;
