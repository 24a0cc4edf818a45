//! Write, read back with the official `mcap` crate, compare; same input → same bytes; files
//! that end early or carry a corrupt byte are read as far as they are intact; an existing
//! recording is never replaced unless asked.

use recorder::{
    read, FileState, Frame, Overwrite, RecordError, RecordOptions, Recorder, Telemetry, Truth,
};
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

fn end() -> BTreeMap<String, String> {
    BTreeMap::from([("reason".to_string(), "completed".to_string())])
}

fn write(path: &std::path::Path, data: &[Frame]) {
    let meta = BTreeMap::from([("seed".to_string(), "7".to_string())]);
    let mut r = Recorder::create(path, meta, RecordOptions::default()).unwrap();
    for f in data {
        r.push(*f).unwrap();
    }
    let stats = r.finish(end()).unwrap();
    assert_eq!(stats.messages, 2 * data.len() as u64);
    assert_eq!(stats.dropped_frames, 0);
}

#[test]
fn frames_survive_the_round_trip_bit_for_bit() {
    let data = frames(100_000); // more than the ring holds: exercises waiting
    let path = tmp("rt.mcap");
    write(&path, &data);
    let rec = read(&path).unwrap();
    let report = rec.report.unwrap();
    assert_eq!(report.messages, 200_000);
    assert_eq!(report.state, FileState::Finished);
    assert_eq!(rec.metadata["seed"], "7");
    assert_eq!(rec.end["reason"], "completed");
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
        RecordOptions::default(),
    )
    .err()
    .expect("must fail");
    let msg = err.to_string();
    assert!(msg.contains("/nonexistent-dir/run.mcap"), "{msg}");
}

/// Every file record the MCAP spec names, by opcode, in `bytes` (a finished file).
fn opcodes(bytes: &[u8]) -> Vec<u8> {
    mcap::read::LinearReader::new(bytes)
        .unwrap()
        .map(|r| r.unwrap().opcode())
        .collect()
}

/// What Foxglove's indexed reader needs: profile `ros2`, message indexes for every chunk that
/// holds messages (a chunk index with non-zero times and no message indexes is what
/// `@mcap/core`'s `McapIndexedReader` rejects), chunk indexes and statistics in the summary.
#[test]
fn files_carry_message_indexes_and_the_ros2_profile() {
    let path = tmp("indexed.mcap");
    write(&path, &frames(50_000));
    let bytes = std::fs::read(&path).unwrap();
    let ops = opcodes(&bytes);
    let count = |op: u8| ops.iter().filter(|&&o| o == op).count();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    assert_eq!(summary.stats.unwrap().message_count, 100_000);
    let with_messages: Vec<_> = summary
        .chunk_indexes
        .iter()
        .filter(|c| c.message_end_time > 0)
        .collect();
    assert!(with_messages.len() >= 2, "{:?}", summary.chunk_indexes);
    for c in &summary.chunk_indexes {
        assert!(
            !c.message_index_offsets.is_empty()
                || (c.message_start_time, c.message_end_time) == (0, 0),
            "chunk at {} has times but no message indexes",
            c.chunk_start_offset
        );
    }
    let indexed: usize = with_messages
        .iter()
        .map(|c| c.message_index_offsets.len())
        .sum();
    assert_eq!(
        indexed,
        2 * with_messages.len(),
        "both channels in every chunk"
    );
    assert_eq!(count(mcap::records::op::MESSAGE_INDEX), indexed);
    assert!(count(mcap::records::op::STATISTICS) == 1);
    match mcap::read::LinearReader::new(&bytes).unwrap().next() {
        Some(Ok(mcap::records::Record::Header(h))) => assert_eq!(h.profile, "ros2"),
        other => panic!("first record {other:?}"),
    }
}

/// A file cut anywhere (a killed run, a full disk) is read up to its last complete record:
/// the frames read are exactly the first frames written, every chunk that ended before the
/// cut is recovered whole (the loss is at most the chunk being written), never a panic; cut
/// inside its first records it is rejected with a clear error.
#[test]
fn truncated_files_are_recovered_up_to_the_cut() {
    let data = frames(60_000);
    let path = tmp("whole.mcap");
    write(&path, &data);
    let bytes = std::fs::read(&path).unwrap();
    let chunks = mcap::Summary::read(&bytes).unwrap().unwrap().chunk_indexes;
    let cut = tmp("cut.mcap");
    for k in 1..40 {
        let at = bytes.len() * k / 40;
        std::fs::write(&cut, &bytes[..at]).unwrap();
        match read(&cut) {
            Ok(rec) => {
                let report = rec.report.unwrap();
                assert_eq!(report.state, FileState::Unfinished, "cut at {at}");
                let n = rec.frames.len();
                assert!(rec.frames[..] == data[..n], "cut at {at}: frames differ");
                let complete_until = chunks
                    .iter()
                    .filter(|c| !c.message_index_offsets.is_empty())
                    .filter(|c| (c.chunk_start_offset + c.chunk_length) as usize <= at)
                    .map(|c| c.message_end_time)
                    .max();
                let must = complete_until
                    .map_or(0, |end| data.iter().filter(|f| f.time_ns <= end).count());
                assert!(n >= must, "cut at {at}: {n} frames < {must}");
                assert!(report.to_string().contains("unfinished"), "{report}");
            }
            Err(e) => {
                assert!(at < 1000, "cut at {at}: {e}");
                assert!(e.to_string().contains("cut.mcap"), "{e}");
            }
        }
    }
}

/// A flipped byte inside a chunk fails its CRC: reported with where it was found, the frames
/// before that chunk still read.
#[test]
fn a_flipped_byte_is_reported() {
    let data = frames(60_000);
    let path = tmp("flip.mcap");
    write(&path, &data);
    let mut bytes = std::fs::read(&path).unwrap();
    let chunks = mcap::Summary::read(&bytes).unwrap().unwrap().chunk_indexes;
    let last = chunks.iter().max_by_key(|c| c.chunk_start_offset).unwrap();
    let at = (last.chunk_start_offset + last.chunk_length / 2) as usize;
    bytes[at] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let rec = read(&path).unwrap();
    match rec.report.unwrap().state {
        FileState::Corrupt {
            before_byte,
            reason,
        } => {
            assert!(before_byte as usize >= at, "{before_byte} < {at}");
            assert!(!reason.is_empty());
        }
        other => panic!("flipped byte at {at} not reported: {other:?}"),
    }
    assert!(!rec.frames.is_empty());
    assert!(rec.frames[..] == data[..rec.frames.len()]);
}
/// An existing recording is kept unless `Overwrite::Replace`; the refused run leaves no
/// temporary file behind, and a replacing one leaves only the new file.
#[test]
fn existing_recordings_are_not_overwritten() {
    let path = tmp("keep.mcap");
    write(&path, &frames(100));
    let before = std::fs::read(&path).unwrap();
    let err = Recorder::create(&path, BTreeMap::new(), RecordOptions::default())
        .err()
        .expect("refused");
    assert!(matches!(err, RecordError::Exists { .. }));
    assert!(err.to_string().contains("keep.mcap") && err.to_string().contains("--overwrite"));
    assert_eq!(std::fs::read(&path).unwrap(), before);
    let options = RecordOptions {
        overwrite: Overwrite::Replace,
        ..Default::default()
    };
    let mut r = Recorder::create(&path, BTreeMap::new(), options).unwrap();
    r.push(frames(1)[0]).unwrap();
    r.finish(end()).unwrap();
    assert_ne!(std::fs::read(&path).unwrap(), before);
    assert!(!recorder::partial_path(&path).exists());
}
