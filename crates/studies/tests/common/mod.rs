//! What the study tests share.

/// The resolved plan of `l` (every test configuration is valid).
pub fn plan(l: &runner::config::Loaded) -> runner::Plan {
    runner::Plan::new(l).unwrap()
}
