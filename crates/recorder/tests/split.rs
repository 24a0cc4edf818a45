//! A split recording: numbered parts, each a whole file that reads intact on its own, that
//! together hold every tick once, in order; a part that may not be written ends the run with
//! the parts before it finished and the file in its way untouched.

use crate::common;

use common::{end, frames, tmp};
use recorder::{first_part_of, part_path, read, FileState, RecordError, RecordOptions, Recorder};
use std::collections::BTreeMap;
use std::num::NonZeroU64;

/// 20 ms parts.
const SPAN_NS: u64 = 20_000_000;

fn options() -> RecordOptions {
    RecordOptions {
        split_ns: NonZeroU64::new(SPAN_NS),
        ..Default::default()
    }
}

#[test]
fn parts_hold_every_tick_once_in_order() {
    let path = tmp("soak.mcap");
    let data = frames(50_000); // 0.2505 s at 199.6 kHz
    let mut r = Recorder::create(&path, BTreeMap::new(), options()).unwrap();
    for f in &data {
        r.push(*f).unwrap();
    }
    let stats = r.finish(end()).unwrap();
    assert_eq!(stats.messages, 2 * data.len() as u64);
    assert!(!path.exists(), "a split recording writes parts only");

    // A part per 20 ms of run time begun: the last frame is at 250.5 ms.
    let last_ns = data.last().unwrap().time_ns;
    let parts = (last_ns / SPAN_NS + 1) as u32;
    assert_eq!(parts, 13);
    assert!(!part_path(&path, parts).exists());
    let mut joined = Vec::new();
    for i in 0..parts {
        let part = part_path(&path, i);
        let rec = read(&part).unwrap();
        let report = rec.report.as_ref().unwrap();
        assert_eq!(report.state, FileState::Finished, "{}", part.display());
        assert!(!report.is_damaged(), "{}", part.display());
        assert_eq!(
            rec.metadata["part"],
            i.to_string(),
            "the run record names its part"
        );
        assert_eq!(rec.end["part"], i.to_string());
        assert_eq!(rec.end["part_first_tick"], joined.len().to_string());
        assert_eq!(rec.end["part_ticks"], rec.frames.len().to_string());
        // Each part covers its own 20 ms of run time.
        let lo = u64::from(i) * SPAN_NS;
        assert!(rec
            .frames
            .iter()
            .all(|f| (lo..lo + SPAN_NS).contains(&f.time_ns)));
        if i + 1 < parts {
            assert_eq!(rec.end["reason"], "split");
            let next = part_path(&path, i + 1);
            assert_eq!(
                rec.end["next_part"],
                next.file_name().unwrap().to_str().unwrap()
            );
        } else {
            assert_eq!(
                rec.end["reason"], "completed",
                "the last part ends as the run did"
            );
        }
        joined.extend(rec.frames);
    }
    assert_eq!(joined, data, "every tick once, in order, bit for bit");
}

#[test]
fn a_part_in_the_way_ends_the_run_with_the_parts_before_it_finished() {
    let path = tmp("blocked.mcap");
    let in_the_way = part_path(&path, 2);
    std::fs::write(&in_the_way, b"someone else's file").unwrap();
    let mut r = Recorder::create(&path, BTreeMap::new(), options()).unwrap();
    let mut refused = None;
    for f in frames(50_000) {
        if let Err(e) = r.push(f) {
            refused = Some(e);
            break;
        }
    }
    assert!(
        matches!(refused, Some(RecordError::WriterGone)),
        "{refused:?}"
    );
    let failed = r.finish(end()).unwrap_err();
    assert!(
        matches!(failed, RecordError::WriteFailed { .. }),
        "{failed}"
    );
    assert_eq!(std::fs::read(&in_the_way).unwrap(), b"someone else's file");
    let first = read(&part_path(&path, 0)).unwrap();
    assert_eq!(first.end["reason"], "split");
    let second = read(&part_path(&path, 1)).unwrap();
    assert_eq!(second.report.as_ref().unwrap().state, FileState::Finished);
    assert!(second.end.contains_key("write_failed"), "{:?}", second.end);
    assert_eq!(
        second.end["recorded_ticks"],
        second.frames.len().to_string(),
        "the part says what it holds"
    );
}

#[test]
fn a_parts_name_leads_back_to_the_first() {
    let path = tmp("run.mcap");
    assert_eq!(
        first_part_of(&part_path(&path, 17)),
        Some(part_path(&path, 0))
    );
    for other in ["run.mcap", "run_17.mcap", "run_0001x.mcap", "run_00017.txt"] {
        assert_eq!(first_part_of(&tmp(other)), None, "{other}");
    }
}
