//! Writes fts_plant.pc and fts_plant-config.cmake beside the built library.

fn main() {
    ffi_support::write_package_files("fts_plant", "the fts-servo simulated stage as a C ABI");
    println!("cargo:rerun-if-changed=build.rs");
}
