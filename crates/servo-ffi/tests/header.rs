//! include/fts_servo.h is what cbindgen makes of this crate (cbindgen.toml): the test fails when
//! the checked-in header is stale, and `FTS_WRITE_HEADERS=1` rewrites it.

#[test]
fn the_checked_in_header_is_the_generated_one() {
    ffi_support::check_header(env!("CARGO_MANIFEST_DIR"), "fts_servo.h");
}
