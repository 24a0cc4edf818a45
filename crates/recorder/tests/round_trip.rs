//! Write, read back with our reader and with the official `mcap` crate, compare; same input →
//! same data bytes; files that end early or carry a corrupt byte are read as far as they are
//! intact; an existing recording is never replaced unless asked.

use crate::common;
use recorder::{
    read, FileState, Frame, Overwrite, RecordError, RecordOptions, Recorder, DEFAULT_EPOCH_NS,
    OVERVIEW_PERIOD_NS,
};

use common::{end, frames, tmp, write};
use std::collections::BTreeMap;

#[test]
fn frames_survive_the_round_trip_bit_for_bit() {
    let data = frames(100_000); // more than the ring holds: exercises waiting
    let path = tmp("rt.mcap");
    write(&path, &data);
    let rec = read(&path).unwrap();
    let report = rec.report.unwrap();
    assert_eq!(report.messages, 200_000);
    assert_eq!(report.state, FileState::Finished);
    assert!(report.is_intact(), "{report}");
    // Every CRC is written, and the official reader (which checks each one it is given)
    // reads the whole file.
    let bytes = std::fs::read(&path).unwrap();
    let mut crcs = Vec::new();
    for r in mcap::read::LinearReader::new(&bytes).unwrap() {
        match r.unwrap() {
            mcap::records::Record::DataEnd(d) => crcs.push(d.data_section_crc),
            mcap::records::Record::Footer(f) => crcs.push(f.summary_crc),
            mcap::records::Record::Chunk { header, .. } => crcs.push(header.uncompressed_crc),
            _ => {}
        }
    }
    assert!(crcs.len() > 3 && crcs.iter().all(|&c| c != 0), "{crcs:?}");
    assert_eq!(rec.metadata["seed"], "7");
    assert_eq!(rec.end["reason"], "completed");
    assert!(rec.frames == data);
}

/// Same frames → the same messages byte for byte, the same `run` and `end` records (one
/// fingerprint); the `environment` and `timing` records are the only difference.
#[test]
fn same_frames_same_data_bytes() {
    let data = frames(30_000);
    let (a, b) = (tmp("a.mcap"), tmp("b.mcap"));
    write(&a, &data);
    std::thread::sleep(std::time::Duration::from_millis(5)); // a different start time
    write(&b, &data);
    assert_eq!(
        recorder::fingerprint(&a).unwrap(),
        recorder::fingerprint(&b).unwrap()
    );
    assert_ne!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let names = |p: &std::path::Path| {
        let bytes = std::fs::read(p).unwrap();
        mcap::read::LinearReader::new(&bytes)
            .unwrap()
            .filter_map(|r| match r.unwrap() {
                mcap::records::Record::Metadata(m) => Some(m.name.clone()),
                _ => None,
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(names(&a), ["run", "environment", "end", "timing"]);
    // The official reader sees the same messages: both channels and the 1 kHz overview.
    let count = mcap::MessageStream::new(&std::fs::read(&a).unwrap())
        .unwrap()
        .count();
    assert_eq!(count, 2 * 30_000 + 151);
}

/// Log times are dates: the run's t = 0 is the epoch (2026-01-01 by default, in the `run`
/// record), and the 1 kHz overview's min/max/mean agree with the frames they summarise.
#[test]
fn log_times_start_at_the_epoch_and_the_overview_summarises_each_millisecond() {
    let data = frames(1_000);
    let path = tmp("epoch.mcap");
    write(&path, &data);
    let rec = read(&path).unwrap();
    assert_eq!(
        rec.metadata["log_time_epoch_ns"],
        DEFAULT_EPOCH_NS.to_string()
    );
    let bytes = std::fs::read(&path).unwrap();
    let mut overview = Vec::new();
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert!(m.log_time >= DEFAULT_EPOCH_NS);
        if m.channel.topic == "/overview" {
            use recorder::Message;
            overview.push((
                m.log_time - DEFAULT_EPOCH_NS,
                recorder::Overview::decode(&m.data).unwrap(),
            ));
        }
    }
    // 1 000 ticks at 199.6 kHz span 5.006 ms: six periods.
    assert_eq!(overview.len(), 6);
    for (start, o) in &overview {
        let inside: Vec<_> = data
            .iter()
            .filter(|f| f.time_ns / OVERVIEW_PERIOD_NS == start / OVERVIEW_PERIOD_NS)
            .collect();
        assert_eq!(o.ticks as usize, inside.len());
        let measured = inside.iter().map(|f| f.telemetry.measured_m);
        assert_eq!(o.max.measured_m, measured.clone().fold(f32::MIN, f32::max));
        assert_eq!(o.min.measured_m, measured.clone().fold(f32::MAX, f32::min));
        let mean = measured.map(f64::from).sum::<f64>() / inside.len() as f64;
        assert!((f64::from(o.mean.measured_m) - mean).abs() <= 1e-7 * mean.abs());
    }
}

/// `every = 7`: the full-rate channels hold ticks 0, 7, 14, … bit for bit, the `run` record
/// says so, and the overview is the same as the full recording's (it sees every tick).
#[test]
fn decimated_recordings_keep_every_nth_tick_and_the_whole_overview() {
    let data = frames(10_000);
    let (full, every7) = (tmp("full.mcap"), tmp("every7.mcap"));
    write(&full, &data);
    let options = RecordOptions {
        every: std::num::NonZeroU32::new(7).unwrap(),
        ..Default::default()
    };
    let mut r = Recorder::create(&every7, BTreeMap::new(), options).unwrap();
    for f in &data {
        r.push(*f).unwrap();
    }
    assert_eq!(r.finish(end()).unwrap().messages, 2 * 1_429);
    let rec = read(&every7).unwrap();
    assert_eq!(rec.metadata["record_every"], "7");
    let kept: Vec<Frame> = data.iter().step_by(7).copied().collect();
    assert!(rec.frames == kept);
    let overview = |p: &std::path::Path| {
        let bytes = std::fs::read(p).unwrap();
        mcap::MessageStream::new(&bytes)
            .unwrap()
            .map(Result::unwrap)
            .filter(|m| m.channel.topic == "/overview")
            .map(|m| (m.log_time, m.data.into_owned()))
            .collect::<Vec<_>>()
    };
    let o = overview(&every7);
    assert_eq!(o.len(), 51); // 10 000 ticks span 50.1 ms
    assert_eq!(o, overview(&full));
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
    let stats = summary.stats.clone().unwrap();
    // 50 000 ticks at 199.6 kHz: 250.5 ms, 251 overview periods.
    assert_eq!(stats.message_count, 100_000 + 251);
    assert_eq!(
        stats
            .channel_message_counts
            .values()
            .copied()
            .collect::<Vec<_>>(),
        [50_000, 50_000, 251]
    );
    // 20 ms data chunks (13) and one overview chunk.
    assert_eq!(
        summary.chunk_indexes.len(),
        14,
        "{:?}",
        summary.chunk_indexes
    );
    for c in &summary.chunk_indexes {
        assert!(
            !c.message_index_offsets.is_empty(),
            "chunk at {} has no message indexes",
            c.chunk_start_offset
        );
        assert!(
            c.message_end_time - c.message_start_time < 20_000_000
                || c.message_index_offsets.len() == 1
        );
    }
    let indexed: usize = summary
        .chunk_indexes
        .iter()
        .map(|c| c.message_index_offsets.len())
        .sum();
    assert_eq!(
        indexed,
        2 * 13 + 1,
        "both data channels in every data chunk"
    );
    assert_eq!(count(mcap::records::op::MESSAGE_INDEX), indexed);
    assert!(count(mcap::records::op::STATISTICS) == 1);
    // Through the official crate's index reading: every message of every chunk is indexed,
    // and an index entry leads to the message it names.
    let mut through_indexes = 0;
    for c in &summary.chunk_indexes {
        let indexes = summary.read_message_indexes(&bytes, c).unwrap();
        for (channel, entries) in &indexes {
            through_indexes += entries.len() as u64;
            let last = entries.last().unwrap();
            let m = summary.seek_message(&bytes, c, last).unwrap();
            assert_eq!((m.channel.id, m.log_time), (channel.id, last.log_time));
        }
    }
    assert_eq!(through_indexes, stats.message_count);
    assert_eq!(
        mcap::MessageStream::new(&bytes).unwrap().count() as u64,
        stats.message_count
    );
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
                    .filter(|c| c.message_index_offsets.contains_key(&1))
                    .filter(|c| (c.chunk_start_offset + c.chunk_length) as usize <= at)
                    .map(|c| c.message_end_time - DEFAULT_EPOCH_NS)
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

/// A flipped byte inside a chunk fails its check: that chunk is reported with its offset and
/// skipped, every frame before and after it is still read.
#[test]
fn a_flipped_byte_is_reported_and_the_rest_is_read() {
    let data = frames(60_000);
    let path = tmp("flip.mcap");
    write(&path, &data);
    let mut bytes = std::fs::read(&path).unwrap();
    let chunks = mcap::Summary::read(&bytes).unwrap().unwrap().chunk_indexes;
    let mut data_chunks: Vec<_> = chunks
        .iter()
        .filter(|c| c.message_index_offsets.contains_key(&1))
        .collect();
    data_chunks.sort_by_key(|c| c.chunk_start_offset);
    let hit = data_chunks[data_chunks.len() / 2];
    let at = (hit.chunk_start_offset + hit.chunk_length / 2) as usize;
    bytes[at] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let rec = read(&path).unwrap();
    let report = rec.report.unwrap();
    assert_eq!(report.state, FileState::Finished);
    assert_eq!(report.bad_count, 1);
    assert_eq!(report.bad[0].at_byte, hit.chunk_start_offset);
    assert!(
        report
            .to_string()
            .contains(&format!("at byte {}", hit.chunk_start_offset)),
        "{report}"
    );
    let (lost_from, lost_to) = (
        hit.message_start_time - DEFAULT_EPOCH_NS,
        hit.message_end_time - DEFAULT_EPOCH_NS,
    );
    let kept: Vec<Frame> = data
        .iter()
        .filter(|f| f.time_ns < lost_from || f.time_ns > lost_to)
        .copied()
        .collect();
    assert!(kept.len() < data.len() && kept.len() > data.len() / 2);
    assert!(rec.frames == kept, "the frames around the corrupt chunk");
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
    assert!(err.to_string().contains("keep.mcap") && err.to_string().contains("overwrite"));
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
