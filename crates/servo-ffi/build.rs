//! Writes fts_servo.pc and fts_servo-config.cmake beside the built libraries.

fn main() {
    ffi_support::write_package_files("fts_servo", "the fts-servo controller as a C ABI");
    println!("cargo:rerun-if-changed=build.rs");
}
