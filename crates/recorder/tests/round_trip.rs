//! Write, read back with the official `mcap` crate, compare; same input → same bytes.

use recorder::{read, Frame, Recorder, Telemetry, Truth, WhenFull};
use std::collections::BTreeMap;
use std::path::PathBuf;

fn frames(n: usize) -> Vec<Frame> {
    (0..n)
        .map(|k| {
            let t = k as f64 / 199_600.0;
            Frame {
                time_ns: (t * 1e9).round() as u64,
                telemetry: Telemetry {
                    reference_m: (1e-9 * (t * 300.0).sin()) as f32,
                    measured_m: k as f32 * 1e-12,
                    following_error_m: -1e-10,
                    control_v: 0.1,
                    accel_m_s2: 0.0,
                    flags: (k % 3) as f32,
                },
                truth: Truth {
                    tool_m: 2e-9,
                    cutting_force_n: 1.0,
                    ..Default::default()
                },
            }
        })
        .collect()
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("fts-recorder-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn write(path: &std::path::Path, data: &[Frame]) {
    let meta = BTreeMap::from([("seed".to_string(), "7".to_string())]);
    let mut r = Recorder::create(path, meta, WhenFull::Wait).unwrap();
    for f in data {
        r.push(*f).unwrap();
    }
    let stats = r.finish().unwrap();
    assert_eq!(stats.messages, 2 * data.len() as u64);
    assert_eq!(stats.dropped_frames, 0);
}

#[test]
fn frames_survive_the_round_trip_bit_for_bit() {
    let data = frames(100_000); // more than the ring holds: exercises waiting
    let path = tmp("rt.mcap");
    write(&path, &data);
    let rec = read(&path).unwrap();
    assert_eq!(rec.messages, 200_000);
    assert_eq!(rec.metadata["seed"], "7");
    assert!(rec.frames == data);
}

#[test]
fn same_frames_same_bytes() {
    let data = frames(30_000);
    let (a, b) = (tmp("a.mcap"), tmp("b.mcap"));
    write(&a, &data);
    write(&b, &data);
    assert!(std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap());
}

#[test]
fn unwritable_path_is_a_clear_error() {
    let err = Recorder::create(
        std::path::Path::new("/nonexistent-dir/run.mcap"),
        BTreeMap::new(),
        WhenFull::Wait,
    )
    .err()
    .expect("must fail");
    let msg = err.to_string();
    assert!(msg.contains("/nonexistent-dir/run.mcap"), "{msg}");
}
