//! Points an MCAP file being written can go back to: after its opening records and after each
//! chunk. When a write fails (a full disk, a file size limit, a quota) the writer truncates the
//! file to the last mark — and to earlier ones while finishing still does not fit — so the run
//! ends with a finished, shorter recording rather than an unfinished one.

use std::collections::VecDeque;

/// Counts for the statistics record.
#[derive(Default, Clone)]
pub(crate) struct Counts {
    pub messages: u64,
    pub attachments: u32,
    pub metadata: u32,
    pub chunks: u32,
    pub start_ns: Option<u64>,
    pub end_ns: u64,
    /// Messages per channel id.
    pub per_channel: Vec<u64>,
}

/// The state of a file at a record boundary: where it ends, the CRC so far, how much of each
/// summary index it holds and its counts.
#[derive(Clone)]
pub(crate) struct Mark {
    pub position: u64,
    pub data_crc: crc32fast::Hasher,
    pub chunk_indexes: usize,
    pub attachment_indexes: usize,
    pub metadata_indexes: usize,
    pub counts: Counts,
}

/// Marks kept: each going back frees at least a chunk, far more than the summary needs, so a
/// few always suffice.
const KEPT: usize = 16;

/// The latest marks, newest last.
#[derive(Default)]
pub(crate) struct Marks(VecDeque<Mark>);

impl Marks {
    /// Adds the newest mark (forgetting the oldest beyond [`KEPT`]).
    pub fn push(&mut self, m: Mark) {
        if self.0.len() == KEPT {
            self.0.pop_front();
        }
        self.0.push_back(m);
    }

    /// The newest mark, removed.
    pub fn pop(&mut self) -> Option<Mark> {
        self.0.pop_back()
    }
}
