//! An MCAP recording as `servo inspect`, `servo replay` and `servo verify` read it: streamed
//! with every check (chunk CRCs and indexes, summary, footer), its indexed records found
//! through the summary, its fingerprint taken.

use crate::Scratch;
use recorder::{Frame, Visit};
use std::collections::BTreeMap;

/// Touches everything a reader hands over.
#[derive(Default)]
struct Everything {
    bytes: usize,
}

impl Visit for Everything {
    fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
        self.bytes += name.len() + values.len();
    }
    fn attachment(&mut self, name: &str, data: &[u8]) {
        self.bytes += name.len() + data.len();
    }
    fn frame(&mut self, frame: &Frame) {
        self.bytes += usize::from(frame.time_ns != 0);
    }
    fn message(&mut self, topic: &str, _sequence: u32, _time_ns: u64, data: &[u8]) {
        self.bytes += topic.len() + data.len();
    }
}

/// A recording's bytes; accepted when the file is intact (finished, every check passed).
pub fn mcap(scratch: &Scratch, data: &[u8]) -> bool {
    let path = scratch.file("run.mcap", data);
    let mut seen = Everything::default();
    let intact = recorder::stream(&path, &mut seen).is_ok_and(|report| {
        std::hint::black_box(report.to_string());
        report.is_intact()
    });
    let indexed = recorder::visit_indexed(&path, &mut seen);
    let fingerprint = recorder::fingerprint(&path);
    std::hint::black_box(seen.bytes);
    intact && indexed.is_ok_and(|found| found) && fingerprint.is_ok()
}
