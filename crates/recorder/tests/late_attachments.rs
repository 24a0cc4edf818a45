//! Files a run took up while it ran (a controller `servo ctl load` swapped in) are attached
//! with the `end` record, after the last frame: the summary's index finds them and the `end`
//! record without streaming the frames, the official reader sees the same attachment, and a
//! file without a summary (a killed run) says so instead of guessing.

use crate::common;

use common::{end, frames, tmp};
use recorder::{Input, RecordOptions, Recorder, Visit};
use std::collections::BTreeMap;

/// What the index shows.
#[derive(Default)]
struct Seen {
    metadata: BTreeMap<String, BTreeMap<String, String>>,
    attachments: BTreeMap<String, Vec<u8>>,
    frames: usize,
}

impl Visit for Seen {
    fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
        self.metadata.insert(name.into(), values.clone());
    }
    fn attachment(&mut self, name: &str, data: &[u8]) {
        self.attachments.insert(name.into(), data.to_vec());
    }
    fn frame(&mut self, _: &recorder::Frame) {
        self.frames += 1;
    }
}

fn input(name: &str, data: &[u8]) -> Input {
    Input {
        name: name.into(),
        media_type: "application/toml".into(),
        data: data.to_vec(),
    }
}

#[test]
fn late_attachments_are_found_through_the_index_before_the_frames() {
    let path = tmp("late.mcap");
    let options = RecordOptions {
        inputs: vec![input("controller.toml", b"[controller.pid]\nkp = 1.0\n")],
        ..Default::default()
    };
    let mut r = Recorder::create(&path, BTreeMap::new(), options).unwrap();
    let data = frames(50_000);
    for f in &data {
        r.push(*f).unwrap();
    }
    let swapped = b"[controller.pid]\nkp = 0.5\n";
    r.attach(input("controller_load.1.toml", swapped), 123_456_789);
    r.finish(end()).unwrap();

    let mut seen = Seen::default();
    assert!(recorder::visit_indexed(&path, &mut seen).unwrap());
    assert_eq!(seen.frames, 0, "the index reads no frame");
    assert_eq!(seen.attachments.len(), 2);
    assert_eq!(seen.attachments["controller_load.1.toml"], swapped);
    assert_eq!(seen.metadata["end"]["reason"], "completed");
    assert!(seen.metadata.contains_key("run"));

    // The official reader: the same attachment, at the epoch plus its run time.
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let index = summary
        .attachment_indexes
        .iter()
        .find(|a| a.name == "controller_load.1.toml")
        .unwrap();
    let a = mcap::read::attachment(&bytes, index).unwrap();
    assert_eq!(&a.data[..], swapped);
    assert_eq!(a.log_time, recorder::DEFAULT_EPOCH_NS + 123_456_789);
    // A stream meets it after the last frame.
    let mut streamed = Seen::default();
    recorder::stream(&path, &mut streamed).unwrap();
    assert_eq!(streamed.frames, data.len());
    assert_eq!(streamed.attachments["controller_load.1.toml"], swapped);
}

#[test]
fn a_file_without_a_summary_is_not_guessed_at() {
    let path = tmp("cut.mcap");
    common::write(&path, &frames(20_000));
    let bytes = std::fs::read(&path).unwrap();
    let cut = tmp("cut-short.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() - 100]).unwrap();
    assert!(!recorder::visit_indexed(&cut, &mut Seen::default()).unwrap());
    // An index pointing past the data section is named as damage, not read.
    let mut broken = bytes.clone();
    let footer = broken.len() - 8 - 29;
    let summary_start = u64::from_le_bytes(broken[footer + 9..footer + 17].try_into().unwrap());
    // The metadata index's offset field: find the `end` record's index in the summary.
    let at = find_metadata_index(&broken[summary_start as usize..footer], "end").unwrap()
        + summary_start as usize;
    broken[at + 9..at + 17].copy_from_slice(&u64::MAX.to_le_bytes());
    // The summary CRC no longer matches; our index reader checks records, not that CRC.
    let damaged = tmp("damaged.mcap");
    std::fs::write(&damaged, &broken).unwrap();
    let e = recorder::visit_indexed(&damaged, &mut Seen::default()).unwrap_err();
    assert!(e.to_string().contains("damaged.mcap"), "{e}");
}

/// Offset within `summary` of the metadata index record naming `name`.
fn find_metadata_index(summary: &[u8], name: &str) -> Option<usize> {
    let mut at = 0;
    while at + 9 <= summary.len() {
        let len = u64::from_le_bytes(summary[at + 1..at + 9].try_into().unwrap()) as usize;
        if summary[at] == 0x0D {
            let body = &summary[at + 9..at + 9 + len];
            let n = u32::from_le_bytes(body[16..20].try_into().unwrap()) as usize;
            if &body[20..20 + n] == name.as_bytes() {
                return Some(at);
            }
        }
        at += 9 + len;
    }
    None
}
