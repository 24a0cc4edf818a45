//! One libFuzzer entry per target of `fuzz-targets`: `fts_fuzz::target!(name)` in
//! `fuzz_targets/name.rs`.

#[doc(hidden)]
pub use fuzz_targets;
#[doc(hidden)]
pub use libfuzzer_sys;

/// The scratch folder of this process (under `FTS_FUZZ_SCRATCH`, else the temporary
/// directory; the campaign script removes it).
pub fn scratch() -> &'static fuzz_targets::Scratch {
    static SCRATCH: std::sync::OnceLock<fuzz_targets::Scratch> = std::sync::OnceLock::new();
    SCRATCH.get_or_init(|| fuzz_targets::Scratch::new().expect("a scratch folder"))
}

/// The libFuzzer entry of the target `name`.
#[macro_export]
macro_rules! target {
    ($name:ident) => {
        $crate::libfuzzer_sys::fuzz_target!(|data: &[u8]| {
            let target = $crate::fuzz_targets::target(stringify!($name)).expect("a target");
            target($crate::scratch(), data);
        });
    };
}
