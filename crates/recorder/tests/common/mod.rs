//! What the recorder tests share: synthetic frames, a scratch folder, writing a recording.
#![allow(dead_code)] // each test file uses a part

use recorder::{Frame, RecordOptions, Recorder, TelemetryRecord, TruthRecord};
use std::collections::BTreeMap;
use std::path::PathBuf;

pub fn frames(n: usize) -> Vec<Frame> {
    (0..n)
        .map(|k| {
            let t = k as f64 / 199_600.0;
            Frame {
                time_ns: (t * 1e9).round() as u64,
                telemetry: TelemetryRecord {
                    reference_m: (1e-9 * libm::sin(t * 300.0)) as f32,
                    measured_m: k as f32 * 1e-12,
                    following_error_m: -1e-10,
                    controller_error_m: -2e-10,
                    control_v: 0.1,
                    accel_m_s2: 0.0,
                    flags: (k % 3) as f32,
                },
                truth: TruthRecord {
                    tool_m: 2e-9,
                    cutting_force_n: 1.0,
                    ..Default::default()
                },
            }
        })
        .collect()
}

/// `name` in this test's private scratch folder (random name, 0700), removed when the test's
/// thread — libtest gives each test its own — exits.
pub fn tmp(name: &str) -> PathBuf {
    thread_local! {
        static DIR: tempfile::TempDir = tempfile::Builder::new()
            .prefix("fts-recorder-")
            .tempdir()
            .expect("a private scratch folder");
    }
    DIR.with(|dir| dir.path().join(name))
}

pub fn end() -> BTreeMap<String, String> {
    BTreeMap::from([("reason".to_string(), "completed".to_string())])
}

pub fn write(path: &std::path::Path, data: &[Frame]) {
    let meta = BTreeMap::from([("seed".to_string(), "7".to_string())]);
    let mut r = Recorder::create(path, meta, RecordOptions::default()).unwrap();
    for f in data {
        r.push(*f).unwrap();
    }
    let stats = r.finish(end()).unwrap();
    assert_eq!(stats.messages, 2 * data.len() as u64);
    assert_eq!(stats.dropped_frames, 0);
}
