//! Recorder throughput: [`SECONDS`] simulated seconds of a real closed-loop run (the default
//! thesis prototype, 199.6 kHz, sensor and current noise on: realistic entropy; one simulated
//! second repeated, time-shifted) pushed through the ring, encoded and written as whole-chunk
//! zstd MCAP with message indexes and the overview, finished and synced; the baseline in the
//! same run writes the same CDR payloads back to back to a plain buffered file; a third case
//! records every 10th tick (`--record-every 10`); a fourth hashes a finished recording's bytes
//! with CRC-32, the work the data section's CRC adds to the writer. Several seconds per iteration so the
//! one-off costs of a recording (its final drain and `fdatasync`) weigh as in a long run; divide the time by [`SECONDS`] for the time per
//! simulated second. Prints the bytes per simulated second of each.
#![allow(missing_docs)] // criterion_group! generates undocumented items.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use recorder::{Frame, Message, Overwrite, RecordOptions, Recorder};
use run_config::Loaded;
use std::collections::BTreeMap;
use std::io::Write;
use std::num::NonZeroU32;

/// One simulated second of the default run.
fn frames() -> Vec<Frame> {
    let mut loaded = Loaded::default();
    loaded.config.run.duration_s = 1.0;
    let plan = runner::Plan::new(&loaded).unwrap();
    let mut out = Vec::new();
    runner::run::run_to_end_with(&plan, |f| out.push(*f)).unwrap();
    out
}

/// Simulated seconds per iteration.
const SECONDS: u64 = 16;

/// The frames of [`SECONDS`] simulated seconds: one, repeated and time-shifted.
fn run_of(second: &[Frame]) -> impl Iterator<Item = Frame> + '_ {
    (0..SECONDS).flat_map(move |k| {
        second.iter().map(move |f| Frame {
            time_ns: f.time_ns + k * 1_000_000_000,
            ..*f
        })
    })
}

fn throughput(c: &mut Criterion) {
    let data = frames();
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    let path_of = |every: u32| dir.join(format!("every-{every}.mcap"));
    let mut group = c.benchmark_group("recorder_16s");
    group
        .sample_size(10)
        .throughput(Throughput::Elements(SECONDS * data.len() as u64));
    for every in [1, 10] {
        let name = match every {
            1 => "mcap_zstd".to_string(),
            n => format!("mcap_zstd_every_{n}"),
        };
        group.bench_function(name, |b| {
            b.iter(|| {
                let options = RecordOptions {
                    overwrite: Overwrite::Replace,
                    every: NonZeroU32::new(every).unwrap(),
                    ..Default::default()
                };
                let mut r = Recorder::create(&path_of(every), BTreeMap::new(), options).unwrap();
                for f in run_of(&data) {
                    r.push(f).unwrap();
                }
                r.finish(BTreeMap::new()).unwrap()
            })
        });
    }
    group.bench_function("raw_file_baseline", |b| {
        b.iter(|| {
            let mut w = std::io::BufWriter::with_capacity(
                1 << 20,
                std::fs::File::create(dir.join("raw.bin")).unwrap(),
            );
            let mut buf = Vec::with_capacity(256);
            for f in run_of(&data) {
                buf.clear();
                f.telemetry.encode(&mut buf);
                f.truth.encode(&mut buf);
                w.write_all(&buf).unwrap();
            }
            w.flush().unwrap();
        })
    });
    // The data section's CRC (every byte a recording writes before its Data End record is
    // hashed once as it is written): the same work over a finished recording's bytes, so its
    // cost is read against `mcap_zstd` in the same run.
    let written = std::fs::read(path_of(1)).unwrap();
    group.bench_function("data_section_crc", |b| {
        b.iter(|| crc32fast::hash(std::hint::black_box(&written)))
    });
    group.finish();
    for (what, file) in [
        ("mcap", path_of(1)),
        ("mcap_every_10", path_of(10)),
        ("raw", dir.join("raw.bin")),
    ] {
        let bytes = std::fs::metadata(file).map_or(0, |m| m.len());
        println!(
            "recorder_16s/{what}: {:.1} MB per simulated second",
            bytes as f64 / 1e6 / SECONDS as f64
        );
    }
}

criterion_group!(benches, throughput);
criterion_main!(benches);
