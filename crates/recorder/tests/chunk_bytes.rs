//! The file bytes do not depend on how chunks are compressed: a file written chunk by chunk
//! with its records compressed off the writer's thread is byte for byte the file the
//! single-threaded writer made (its length and CRC-32 recorded from that writer), whatever
//! order the compressors finish in.

use recorder::mcap_file::McapFile;
use std::collections::BTreeMap;

/// A file of two lanes (as the recorder writes them: full-rate data and a slow overview), noisy
/// payloads (compressible like the recorded floats), chunks closed at their size, metadata and
/// an attachment between and after them.
fn file() -> Vec<u8> {
    let mut w = McapFile::create(Vec::new(), "ros2", 2, 1 << 16).unwrap();
    w.schema(1, "fts_servo/Sample", "ros2msg", b"float32 a\nfloat32 b\n");
    w.channel(1, 1, "/data", "cdr");
    w.channel(2, 1, "/overview", "cdr");
    w.metadata("run", &BTreeMap::from([("seed".into(), "1".into())]))
        .unwrap();
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    for k in 0..40_000u32 {
        let t = 1_000_000_000 + u64::from(k) * 5_010;
        let held = w.message(0, 1, k, t, |b| {
            for _ in 0..6 {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Small noisy floats: the low bits random, the exponent steady.
                let v = 1e-9 * ((x % 2001) as f32 - 1000.0);
                b.extend_from_slice(&v.to_le_bytes());
            }
        });
        if held >= 1 << 16 {
            w.close_chunk(0).unwrap();
        }
        if k % 200 == 0 {
            let held = w.message(1, 2, k / 200, t, |b| b.extend_from_slice(&k.to_le_bytes()));
            if held >= 1 << 10 {
                w.close_chunk(1).unwrap();
            }
        }
        if k == 25_000 {
            w.attachment("input.toml", "application/toml", t, b"[run]\nseed = 1\n")
                .unwrap();
        }
    }
    w.metadata(
        "end",
        &BTreeMap::from([("reason".into(), "completed".into())]),
    )
    .unwrap();
    w.finish().unwrap()
}

#[test]
fn the_file_is_the_single_threaded_writers_byte_for_byte() {
    let bytes = file();
    assert_eq!(
        (bytes.len(), crc32fast::hash(&bytes)),
        (GOLDEN_LEN, GOLDEN_CRC),
        "length and CRC-32 of the file"
    );
    // And the same again (the compressors finish in another order each time).
    for _ in 0..3 {
        assert!(file() == bytes);
    }
}

/// Length and CRC-32 of [`file`] as the single-threaded writer (every chunk compressed on the
/// writer's thread, before the next was filled) wrote it.
const GOLDEN_LEN: usize = 2_057_917;
const GOLDEN_CRC: u32 = 3_329_831_851;
