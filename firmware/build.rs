//! Puts memory.x and device.x where cortex-m-rt's link.x finds them, and tells the firmware
//! whether it is built for a double-precision FPU (`cfg(f64_in_hardware)`: `-C
//! target-cpu=cortex-m7`; Rust does not expose the ARM FPU features to `cfg(target_feature)`).

use std::{env, fs, path::PathBuf};

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    for file in ["memory.x", "device.x"] {
        fs::copy(file, out.join(file)).expect("memory.x and device.x sit beside Cargo.toml");
        println!("cargo:rerun-if-changed={file}");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo::rustc-check-cfg=cfg(f64_in_hardware)");
    let flags = env::var("CARGO_ENCODED_RUSTFLAGS").unwrap_or_default();
    let double_fpu = flags
        .split('\x1f')
        .any(|f| f == "target-cpu=cortex-m7" || f.contains("+fp64") || f.contains("+fp-armv8d16"));
    if double_fpu {
        println!("cargo:rustc-cfg=f64_in_hardware");
    }
}
