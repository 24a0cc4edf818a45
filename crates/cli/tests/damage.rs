//! Damage is never reported as success. One recording of the default run, damaged one way at a
//! time — a flipped bit in every region (header, schema and channel records, metadata, each
//! chunk, message indexes, data end, each kind of summary record, summary offsets, footer, the
//! closing magic), a cut at the start and the last byte of each, message payloads cut short, a
//! non-finite embedded configuration, fewer ticks than its end record counts — is refused with a non-zero exit by `servo inspect`,
//! `replay`, `spectrum` and `export`; `--salvage` reads what is intact of a damaged chunk.

use crate::common;

use common::{servo, succeeded, tmp};
use recorder::mcap_file::{op, McapFile, MAGIC};
use recorder::{Message, TelemetryRecord, TruthRecord};
use std::path::{Path, PathBuf};

/// A record of the file: opcode, offset, total length (opcode and length field included).
#[derive(Debug, Clone, Copy)]
struct Span {
    opcode: u8,
    at: usize,
    len: usize,
}

/// Every record of `bytes` in file order, then the closing magic (opcode 0).
fn layout(bytes: &[u8]) -> Vec<Span> {
    let mut spans = Vec::new();
    let mut at = MAGIC.len();
    while at + 9 <= bytes.len() {
        let opcode = bytes[at];
        let len = 9 + u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        spans.push(Span { opcode, at, len });
        at += len;
        if opcode == op::FOOTER {
            break;
        }
    }
    spans.push(Span {
        opcode: 0,
        at,
        len: MAGIC.len(),
    });
    spans
}

/// The base recording: the default run, 0.1 s (several chunks), in a new folder `dir`.
fn base(dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join("base.mcap");
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "0.1", "--out"])
            .arg(&path)
            .output()
            .unwrap(),
    );
    path
}

/// Each command that reads a recording, on `file`: whether it exited 0.
fn exits_ok(file: &Path) -> Vec<(&'static str, bool, String)> {
    let dir = file.with_extension("out");
    std::fs::create_dir_all(&dir).unwrap();
    let runs: [(&str, Vec<std::ffi::OsString>); 4] = [
        ("inspect", vec![file.into()]),
        ("replay", vec![file.into(), "--no-record".into()]),
        (
            "spectrum",
            vec![
                file.into(),
                "--resolution-hz".into(),
                "50".into(),
                "--out-dir".into(),
                dir.join("s").into(),
            ],
        ),
        (
            "export",
            vec![file.into(), "-o".into(), dir.join("x.csv").into()],
        ),
    ];
    runs.into_iter()
        .map(|(command, args)| {
            let out = servo().arg(command).args(&args).output().unwrap();
            let text = String::from_utf8_lossy(&out.stdout).into_owned()
                + &String::from_utf8_lossy(&out.stderr);
            (command, out.status.success(), text)
        })
        .collect()
}

/// Each command that reads a recording refuses `file` with a non-zero exit.
fn refused_by_all(file: &Path, what: &str) {
    for (command, ok, text) in exits_ok(file) {
        assert!(!ok, "{what}: servo {command} exited 0\n{text}");
    }
}

#[test]
fn every_flipped_bit_and_every_cut_is_refused() {
    let dir = tmp("damage");
    let base = base(&dir);
    let bytes = std::fs::read(&base).unwrap();
    // The intact file is read by every command.
    for (command, ok, text) in exits_ok(&base) {
        assert!(ok, "servo {command} refused the intact recording\n{text}");
    }
    let spans = layout(&bytes);
    let summary_start = spans.iter().position(|s| s.opcode == op::DATA_END).unwrap() + 1;
    let mut regions: Vec<(String, Span)> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for (i, s) in spans.iter().enumerate() {
        let section = if i >= summary_start {
            "summary"
        } else {
            "data"
        };
        // Every chunk; one record of every other kind in each section.
        if s.opcode == op::CHUNK || seen.insert((section, s.opcode)) {
            regions.push((
                format!("{section} opcode {:#04x} at {}", s.opcode, s.at),
                *s,
            ));
        }
    }
    let kinds: Vec<u8> = regions.iter().map(|(_, s)| s.opcode).collect();
    for needed in [
        op::HEADER,
        op::SCHEMA,
        op::CHANNEL,
        op::METADATA,
        op::CHUNK,
        op::MESSAGE_INDEX,
        op::DATA_END,
        op::STATISTICS,
        op::CHUNK_INDEX,
        op::METADATA_INDEX,
        op::SUMMARY_OFFSET,
        op::FOOTER,
        0,
    ] {
        assert!(kinds.contains(&needed), "no region of opcode {needed:#04x}");
    }
    assert!(kinds.iter().filter(|&&k| k == op::CHUNK).count() >= 2);
    for (n, (what, s)) in regions.iter().enumerate() {
        // A bit flipped in the middle of the record (past its opcode and length).
        let mut flipped = bytes.clone();
        let inside = if s.len > 9 {
            s.at + 9 + (s.len - 9) / 2
        } else {
            s.at + s.len / 2
        };
        flipped[inside] ^= 0x10;
        let file = dir.join(format!("flip{n}.mcap"));
        std::fs::write(&file, &flipped).unwrap();
        refused_by_all(&file, &format!("bit flipped in {what}"));
        // Cut at its start and before its last byte.
        for cut in [s.at, s.at + s.len - 1] {
            let file = dir.join(format!("cut{n}_{cut}.mcap"));
            std::fs::write(&file, &bytes[..cut]).unwrap();
            refused_by_all(&file, &format!("cut at byte {cut} ({what})"));
        }
    }
}

#[test]
fn salvage_reads_what_is_intact_of_a_damaged_chunk() {
    let dir = tmp("salvage");
    let base = base(&dir);
    let mut bytes = std::fs::read(&base).unwrap();
    let chunk = *layout(&bytes)
        .iter()
        .filter(|s| s.opcode == op::CHUNK)
        .nth(1)
        .unwrap();
    bytes[chunk.at + chunk.len / 2] ^= 0x01;
    let file = dir.join("hit.mcap");
    std::fs::write(&file, &bytes).unwrap();
    let refused = servo().arg("inspect").arg(&file).output().unwrap();
    assert_eq!(refused.status.code(), Some(1));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        err.contains(&format!("at byte {}", chunk.at)) && err.contains("--salvage"),
        "{err}"
    );
    let salvaged = servo()
        .args(["inspect", "--salvage"])
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&salvaged);
    let out = String::from_utf8_lossy(&salvaged.stdout);
    assert!(out.contains("chunk CRC mismatch"), "{out}");
    let csv = dir.join("hit.csv");
    let export = servo()
        .args(["export", "--salvage", "-o"])
        .arg(&csv)
        .arg(&file)
        .output()
        .unwrap();
    succeeded(&export);
    // The ticks of the other chunks are there, fewer than the run's 19 960.
    let rows = std::fs::read_to_string(&csv).unwrap().lines().count() - 1;
    assert!(rows > 1000 && rows < 19_960, "{rows} rows");
}

/// A recording written with every CRC right whose content the reader must still refuse: its
/// `run` record (with `config` replaced by `config`) and its first `frames` frames (None: all),
/// each payload cut to `payload_bytes` (None: whole).
fn rewritten(
    base: &Path,
    out: &Path,
    config: Option<String>,
    payload_bytes: Option<usize>,
    frames: Option<usize>,
) {
    let rec = recorder::read(base).unwrap();
    let mut run = rec.metadata.clone();
    if let Some(c) = config {
        run.insert("config".into(), c);
    }
    let epoch: u64 = run[recorder::EPOCH_KEY].parse().unwrap();
    let file = std::fs::File::create(out).unwrap();
    let mut m = McapFile::create(file, "ros2", 1, 1 << 20).unwrap();
    m.schema(
        1,
        TelemetryRecord::SCHEMA_NAME,
        "ros2msg",
        TelemetryRecord::schema_text().as_bytes(),
    );
    m.schema(
        2,
        TruthRecord::SCHEMA_NAME,
        "ros2msg",
        TruthRecord::schema_text().as_bytes(),
    );
    m.channel(1, 1, TelemetryRecord::TOPIC, "cdr");
    m.channel(2, 2, TruthRecord::TOPIC, "cdr");
    m.metadata("run", &run).unwrap();
    let cut = |buf: &mut Vec<u8>, from: usize| {
        if let Some(n) = payload_bytes {
            buf.truncate(from + n);
        }
    };
    for (seq, f) in rec
        .frames
        .iter()
        .take(frames.unwrap_or(usize::MAX))
        .enumerate()
    {
        let t = epoch + f.time_ns;
        m.message(0, 1, seq as u32, t, |b| {
            let from = b.len();
            f.telemetry.encode(b);
            cut(b, from);
        });
        m.message(0, 2, seq as u32, t, |b| {
            let from = b.len();
            f.truth.encode(b);
            cut(b, from);
        });
    }
    m.metadata("end", &rec.end).unwrap();
    m.finish().unwrap();
}

#[test]
fn short_payloads_and_a_non_finite_configuration_are_refused() {
    let dir = tmp("content");
    let base = base(&dir);
    // The rewrite itself is a good recording.
    let good = dir.join("good.mcap");
    rewritten(&base, &good, None, None, None);
    succeeded(&servo().arg("inspect").arg(&good).output().unwrap());
    let short = dir.join("short.mcap");
    rewritten(&base, &short, None, Some(8), None);
    refused_by_all(&short, "payloads cut to 8 bytes");
    let err = servo().arg("inspect").arg(&short).output().unwrap().stderr;
    assert!(
        String::from_utf8_lossy(&err).contains("/telemetry message of 8 bytes"),
        "{}",
        String::from_utf8_lossy(&err)
    );
    let config = recorder::read(&base).unwrap().metadata["config"].clone();
    let nan = config.replacen("duration_s = 0.1", "duration_s = nan", 1);
    assert_ne!(nan, config);
    let bad = dir.join("nan.mcap");
    rewritten(&base, &bad, Some(nan), None, None);
    refused_by_all(&bad, "duration_s = nan");
    let out = servo().arg("inspect").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("nan.mcap (its configuration)") && err.contains("run.duration_s"),
        "{err}"
    );
    // A file that holds fewer ticks than its end record counts (every CRC right).
    let fewer = dir.join("fewer.mcap");
    rewritten(&base, &fewer, None, None, Some(1000));
    for (command, ok, text) in exits_ok(&fewer) {
        // export copies what the file holds; the commands that read it as a run refuse it.
        assert_eq!(ok, command == "export", "servo {command}: {text}");
    }
    let err = servo().arg("replay").arg(&fewer).output().unwrap().stderr;
    assert!(
        String::from_utf8_lossy(&err)
            .contains("its end record counts 19960 ticks, the file holds 1000"),
        "{}",
        String::from_utf8_lossy(&err)
    );
}
