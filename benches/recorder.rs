//! Recorder throughput: one simulated second of a real closed-loop run (the default thesis
//! prototype, 199.6 kHz, sensor and current noise on: realistic entropy) pushed through the
//! ring, encoded and written as whole-chunk zstd MCAP with message indexes and the overview,
//! as a multiple of real time; the baseline in the same run writes the same CDR payloads back
//! to back to a plain buffered file. Prints the bytes per simulated second of each.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use recorder::{Frame, Message, Overwrite, RecordOptions, Recorder};
use runner::config::Loaded;
use std::collections::BTreeMap;
use std::io::Write;

/// One simulated second of the default run.
fn frames() -> Vec<Frame> {
    let mut loaded = Loaded::default();
    loaded.config.run.duration_s = 1.0;
    let plan = runner::Plan::new(&loaded).unwrap();
    let mut out = Vec::new();
    runner::run::run_to_end_with(&plan, |f| out.push(*f)).unwrap();
    out
}

fn throughput(c: &mut Criterion) {
    let data = frames();
    let dir = std::env::temp_dir().join(format!("fts-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bench.mcap");
    let mut group = c.benchmark_group("recorder_1s");
    group
        .sample_size(10)
        .throughput(Throughput::Elements(data.len() as u64));
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
    for (what, file) in [("mcap", &path), ("raw", &dir.join("raw.bin"))] {
        let bytes = std::fs::metadata(file).map_or(0, |m| m.len());
        println!(
            "recorder_1s/{what}: {:.1} MB per simulated second",
            bytes as f64 / 1e6
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

criterion_group!(benches, throughput);
criterion_main!(benches);
