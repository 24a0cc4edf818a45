//! A recording made before contract v6 still reads: its telemetry without the controller's own
//! error (taken as the following error), and its `run` metadata without the telemetry
//! convention key (so readers know its reference was paired with the next reading).

use recorder::{read, TELEMETRY_KEY};
use std::path::Path;

#[test]
fn a_contract_v5_recording_reads_with_its_convention() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/v5_sine.mcap");
    let r = read(&path).unwrap();
    assert_eq!(r.frames.len(), 399);
    assert!(!r.metadata.contains_key(TELEMETRY_KEY));
    // The 500 Hz, 1 µm sine is in it, and the missing field is the following error.
    let peak = r
        .frames
        .iter()
        .map(|f| f.telemetry.reference_m.abs())
        .fold(0.0f32, f32::max);
    assert!((peak - 1e-6).abs() < 1e-8, "{peak}");
    for f in &r.frames {
        assert_eq!(
            f.telemetry.controller_error_m,
            f.telemetry.following_error_m
        );
        let e = f.telemetry.reference_m - f.telemetry.measured_m;
        assert!((e - f.telemetry.following_error_m).abs() <= 1e-6 * peak);
    }
}
