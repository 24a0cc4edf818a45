//! The file bytes do not depend on how chunks are compressed: a file written chunk by chunk
//! with its records compressed off the writer's thread is byte for byte the file the
//! single-threaded writer made (its length and CRC-32 recorded from that writer), whatever
//! order the compressors finish in.

use recorder::mcap_file::{McapFile, Sink};
use std::collections::BTreeMap;
use std::io::Write;

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

/// A storage that refuses to grow past `limit` bytes (a file size limit, a full disk).
struct Limited {
    bytes: Vec<u8>,
    limit: usize,
}

impl Write for Limited {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        let room = self.limit.saturating_sub(self.bytes.len());
        if room == 0 {
            return Err(std::io::Error::from_raw_os_error(27)); // EFBIG
        }
        let n = b.len().min(room);
        self.bytes.extend_from_slice(&b[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Sink for Limited {
    fn truncate(&mut self, len: u64) -> std::io::Result<()> {
        self.bytes.truncate(len as usize);
        Ok(())
    }
}

/// A write that fails mid-file: going back to the last chunk written (and further while the
/// end does not fit) leaves a file the reader takes as finished and whole — its statistics
/// those of the messages it holds, nothing damaged — with the end record written after them.
#[test]
fn a_file_cut_back_at_a_write_failure_finishes_whole() {
    let limit = 200_000;
    let mut w = McapFile::create(
        Limited {
            bytes: Vec::new(),
            limit,
        },
        "ros2",
        2,
        1 << 14,
    )
    .unwrap();
    w.schema(1, "fts_servo/Sample", "ros2msg", b"float32 a\n");
    w.channel(1, 1, "/data", "cdr");
    w.channel(2, 1, "/overview", "cdr");
    w.metadata("run", &BTreeMap::from([("seed".into(), "1".into())]))
        .unwrap();
    w.mark().unwrap();
    let mut failed = None;
    for k in 0..1_000_000u32 {
        let t = u64::from(k) * 5_010;
        let x = (k.wrapping_mul(2_654_435_761) >> 8) as f32;
        if w.message(0, 1, k, t, |b| b.extend_from_slice(&x.to_le_bytes())) >= 1 << 14 {
            if let Err(e) = w.close_chunk(0) {
                failed = Some(e);
                break;
            }
        }
        if k % 100 == 0 {
            w.message(1, 2, k / 100, t, |b| b.extend_from_slice(&k.to_le_bytes()));
        }
    }
    assert_eq!(
        failed.expect("the limit is reached").raw_os_error(),
        Some(27)
    );
    let end = BTreeMap::from([("reason".into(), "write-failed".into())]);
    let mut rewound = 0;
    let finished = loop {
        assert!(w.rewind().unwrap(), "a mark is left");
        rewound += 1;
        if w.metadata("end", &end).and_then(|()| w.close()).is_ok() {
            break w.into_sink();
        }
    };
    assert!(rewound >= 1);
    assert!(finished.bytes.len() <= limit);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cut.mcap");
    std::fs::write(&path, &finished.bytes).unwrap();
    struct Ends(Vec<String>, u64);
    impl recorder::Visit for Ends {
        fn metadata(&mut self, name: &str, _: &BTreeMap<String, String>) {
            self.0.push(name.to_owned());
        }
        fn message(&mut self, _: &str, _: u32, _: u64, _: &[u8]) {
            self.1 += 1;
        }
    }
    let mut seen = Ends(Vec::new(), 0);
    let report = recorder::stream(&path, &mut seen).unwrap();
    assert_eq!(report.state, recorder::FileState::Finished);
    assert_eq!(report.bad_count, 0, "{:?}", report.bad);
    assert_eq!(seen.0, ["run", "end"]);
    assert!(seen.1 > 3_000, "{} messages kept", seen.1);
}
