//! Replaying a recording: the run rebuilt from what the file holds (its configuration, seed
//! and embedded input files), run again — as it was, to show that it reproduces, or with a
//! replaced controller, feedforward or plant, to show what the run would have been — and the
//! two compared: data channels by digest, metrics side by side.

use crate::config::RunConfig;
use crate::plan::{Plan, CONTROLLER_INPUT};
use crate::recording::{FrameSink, RunHeader};
use crate::RunError;
use recorder::Frame;
use sha2::{Digest, Sha256};

/// Frames per digest block: a difference is located to within this many recorded frames.
pub const DIGEST_BLOCK: u64 = 4096;

/// SHA-256 digests of the data channels (every telemetry and truth value, bit for bit) of
/// consecutive blocks of [`DIGEST_BLOCK`] frames, up to a limit.
#[derive(Debug, Clone)]
pub struct FrameDigest {
    limit: u64,
    frames: u64,
    block: Sha256,
    blocks: Vec<[u8; 32]>,
}

impl FrameDigest {
    /// Digests of the first `limit` frames shown.
    pub fn new(limit: u64) -> Self {
        FrameDigest {
            limit,
            frames: 0,
            block: Sha256::new(),
            blocks: Vec::new(),
        }
    }

    /// Takes the next frame (ignored past the limit).
    pub fn add(&mut self, f: &Frame) {
        if self.frames >= self.limit {
            return;
        }
        for v in f.telemetry.values().iter().chain(&f.truth.values()) {
            self.block.update(v.to_bits().to_le_bytes());
        }
        self.frames += 1;
        if self.frames.is_multiple_of(DIGEST_BLOCK) {
            self.blocks.push(self.block.finalize_reset().into());
        }
    }

    /// Frames digested.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The block digests, the last one partial.
    fn finish(mut self) -> Vec<[u8; 32]> {
        if !self.frames.is_multiple_of(DIGEST_BLOCK) {
            self.blocks.push(self.block.finalize().into());
        }
        self.blocks
    }

    /// The first frame (index among those digested) from which `self` and `other` may differ,
    /// or `None` when both digested the same frames with the same values.
    pub fn first_difference(self, other: FrameDigest) -> Option<u64> {
        let shorter = self.frames.min(other.frames);
        let same_count = self.frames == other.frames;
        let (a, b) = (self.finish(), other.finish());
        match a.iter().zip(&b).position(|(x, y)| x != y) {
            Some(block) => Some(block as u64 * DIGEST_BLOCK),
            None if same_count => None,
            None => Some(shorter),
        }
    }
}

/// What a recording holds for a replay, read in one pass ([`FrameSink`] for
/// [`crate::recording::inspect_with`]): its header, the digest of its frames (up to a limit),
/// and whether its frames carry a simulator's truth (a hardware run's do not).
pub struct Recorded {
    /// Frames digested at most (those before an operator's first change — a controller swap,
    /// a gain change — which a replay does not repeat).
    pub limit: u64,
    /// The run header (configuration, controller, inputs, decimation).
    pub header: Option<RunHeader>,
    /// Digest of every recorded frame.
    pub digest: Option<FrameDigest>,
    /// Whether any frame carried simulator truth (tool position or gap not zero).
    pub has_truth: bool,
}

impl Recorded {
    /// Reads a recording, digesting its first `limit` frames.
    pub fn new(limit: u64) -> Self {
        Recorded {
            limit,
            header: None,
            digest: None,
            has_truth: false,
        }
    }
}

impl FrameSink for Recorded {
    fn header(&mut self, header: &RunHeader) -> Result<(), RunError> {
        self.header = Some(header.clone());
        self.digest = Some(FrameDigest::new(self.limit));
        Ok(())
    }

    fn frame(&mut self, f: &Frame) {
        if let Some(d) = &mut self.digest {
            d.add(f);
        }
        self.has_truth |= f.truth.tool_m != 0.0 || f.truth.gap_m != 0.0;
    }
}

impl RunHeader {
    /// The recorded run with `config` instead of the recorded configuration (a replaced
    /// controller, feedforward or plant): the embedded input files are used where the
    /// configuration still names them, so an unchanged controller file is the recorded copy
    /// and a new one is read from disk.
    pub fn replan(&self, config: RunConfig) -> Result<Plan, RunError> {
        let recorded = &self.loaded.config.controller;
        let same_controller_file = config.controller.ss_file == recorded.ss_file;
        let mut loaded = self.loaded.clone();
        loaded.config = config;
        let inputs = self
            .inputs()
            .into_iter()
            .filter(|i| same_controller_file || i.name != CONTROLLER_INPUT)
            .collect();
        Plan::with_inputs(&loaded, inputs)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(k: u64) -> Frame {
        let mut f = Frame::default();
        f.telemetry.following_error_m = k as f32 * 1e-9;
        f.truth.tool_m = -(k as f32) * 1e-9;
        f
    }

    #[test]
    fn digests_locate_the_first_differing_block() {
        let n = 3 * DIGEST_BLOCK + 17;
        let digest = |change: Option<u64>| {
            let mut d = FrameDigest::new(u64::MAX);
            for k in 0..n {
                let mut f = frame(k);
                if Some(k) == change {
                    // One bit of one value.
                    f.truth.gap_m = f32::from_bits(1);
                }
                d.add(&f);
            }
            d
        };
        assert_eq!(digest(None).first_difference(digest(None)), None);
        for k in [0, DIGEST_BLOCK - 1, 2 * DIGEST_BLOCK + 5, n - 1] {
            let at = digest(None).first_difference(digest(Some(k)));
            assert_eq!(at, Some(k / DIGEST_BLOCK * DIGEST_BLOCK), "change at {k}");
        }
        // A shorter run differs from its last (partial) block; a limit cuts the longer one to
        // match.
        let mut short = FrameDigest::new(u64::MAX);
        let mut limited = FrameDigest::new(DIGEST_BLOCK + 3);
        for k in 0..DIGEST_BLOCK + 3 {
            short.add(&frame(k));
        }
        assert_eq!(
            digest(None).first_difference(short.clone()),
            Some(DIGEST_BLOCK)
        );
        for k in 0..n {
            limited.add(&frame(k));
        }
        assert_eq!(limited.frames(), DIGEST_BLOCK + 3);
        assert_eq!(short.first_difference(limited), None);
    }
}
