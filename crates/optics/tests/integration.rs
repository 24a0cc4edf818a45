//! The crate's integration tests as one binary: `cargo test -p optics --test integration`.

mod prescriptions;
