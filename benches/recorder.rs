//! Recorder throughput: one second of frames at 199.6 kHz (two messages each) pushed through
//! the ring, encoded and written to a zstd-chunked MCAP file, as a multiple of real time; the
//! baseline in the same run writes the same CDR payloads back to back to a plain buffered file.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use recorder::{Frame, Overwrite, RecordOptions, Recorder, Telemetry, Truth};
use std::collections::BTreeMap;
use std::io::Write;

const FRAMES: usize = 199_600;

fn frames() -> Vec<Frame> {
    (0..FRAMES)
        .map(|k| {
            let t = k as f64 / 199_600.0;
            let n = ((k * 2_654_435_761) % 1000) as f32 * 1e-12; // noise-like data, not constant
            Frame {
                time_ns: (t * 1e9).round() as u64,
                telemetry: Telemetry {
                    reference_m: 0.0,
                    measured_m: n,
                    following_error_m: -n,
                    control_v: n * 1e6,
                    accel_m_s2: n * 1e3,
                    flags: 0.0,
                },
                truth: Truth {
                    tool_m: n * 0.3,
                    true_error_m: n * 0.3,
                    gap_m: n,
                    motor_force_n: n * 1e3,
                    cutting_force_n: 0.0,
                    coil_current_a: n * 1e4,
                    current_noise_a: n * 1e2,
                    base_m: n * 0.1,
                    sensor_noise_v: n * 1e5,
                },
            }
        })
        .collect()
}

fn throughput(c: &mut Criterion) {
    let data = frames();
    let dir = std::env::temp_dir().join(format!("fts-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bench.mcap");
    let mut group = c.benchmark_group("recorder_1s");
    group
        .sample_size(10)
        .throughput(Throughput::Elements(FRAMES as u64));
    group.bench_function("mcap_zstd", |b| {
        b.iter(|| {
            let options = RecordOptions {
                overwrite: Overwrite::Replace,
                ..Default::default()
            };
            let mut r = Recorder::create(&path, BTreeMap::new(), options).unwrap();
            for f in &data {
                r.push(*f).unwrap();
            }
            r.finish(BTreeMap::new()).unwrap()
        })
    });
    group.bench_function("raw_file_baseline", |b| {
        b.iter(|| {
            let mut w = std::io::BufWriter::with_capacity(
                1 << 20,
                std::fs::File::create(dir.join("raw.bin")).unwrap(),
            );
            let mut buf = Vec::with_capacity(256);
            for f in &data {
                buf.clear();
                f.telemetry.encode(&mut buf);
                f.truth.encode(&mut buf);
                w.write_all(&buf).unwrap();
            }
            w.flush().unwrap();
        })
    });
    group.finish();
}

criterion_group!(benches, throughput);
criterion_main!(benches);
