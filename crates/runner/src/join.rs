//! Joins a run's two record streams — the controller's telemetry and the plant's truth, as
//! they arrive in blocks over shared memory — into frames, tick by tick (the recorder's and
//! the live view's input). A tick whose telemetry was lost is kept from the truth alone and
//! flagged [`daq_io::flags::NO_TELEMETRY`]; sequence gaps are counted; the blocks' flags say
//! when the run is over. Nothing a publisher sends is taken on trust: a block of another run
//! (the first block names the run), or one [`daq_io::BlockCheck`] refuses (a count above
//! capacity, ticks going backwards), is counted, named and skipped — the valid ticks around it
//! are kept.

use daq_io::{flags, BlockCheck, Telemetry, TelemetryBlock, Truth, TruthBlock};
use recorder::Frame;
use std::collections::VecDeque;

/// Joins the two record streams tick by tick.
#[derive(Default)]
pub struct Joiner {
    telemetry: VecDeque<Telemetry>,
    truth: VecDeque<Truth>,
    next_telemetry: u64,
    next_truth: u64,
    dropped: u64,
    truth_only: u64,
    telemetry_end: bool,
    truth_end: bool,
    plant_faults: u32,
    run_id: Option<u64>,
    telemetry_check: BlockCheck,
    truth_check: BlockCheck,
    bad: BadBlocks,
}

/// Blocks refused: how many, and the first one's stream and reason.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BadBlocks {
    /// Blocks refused.
    pub count: u64,
    /// The first: `telemetry …` or `truth …` and why.
    pub first: Option<String>,
}

impl Joiner {
    /// Takes the telemetry records of one block (or counts it refused).
    pub fn telemetry(&mut self, b: &TelemetryBlock) {
        if !self.same_run("telemetry", b.block, b.run_id) {
            return;
        }
        let records = match self.telemetry_check.check(b) {
            Ok(records) => records,
            Err(why) => return self.refuse(format!("telemetry {why}")),
        };
        self.telemetry_end |= b.flags & flags::END != 0;
        for r in records {
            self.dropped += r.seq.saturating_sub(self.next_telemetry);
            self.next_telemetry = r.seq.saturating_add(1);
            self.telemetry.push_back(*r);
        }
    }

    /// Takes the truth records of one block (or counts it refused).
    pub fn truth(&mut self, b: &TruthBlock) {
        if !self.same_run("truth", b.block, b.run_id) {
            return;
        }
        let records = match self.truth_check.check(b) {
            Ok(records) => records,
            Err(why) => return self.refuse(format!("truth {why}")),
        };
        self.truth_end |= b.flags & flags::END != 0;
        self.plant_faults |= b.flags & flags::PLANT_FAULTS;
        for r in records {
            self.dropped += r.seq.saturating_sub(self.next_truth);
            self.next_truth = r.seq.saturating_add(1);
            self.truth.push_back(*r);
        }
    }

    /// Whether a block of run `id` belongs to the run joined (the first block's); refused and
    /// counted when not.
    fn same_run(&mut self, stream: &str, block: u64, id: u64) -> bool {
        match self.run_id {
            None => {
                self.run_id = Some(id);
                true
            }
            Some(run) if run == id => true,
            Some(run) => {
                self.refuse(format!(
                    "{stream} block {block} is of run {id:016x}, not of the run recorded ({run:016x})"
                ));
                false
            }
        }
    }

    fn refuse(&mut self, why: String) {
        self.bad.count += 1;
        self.bad.first.get_or_insert(why);
    }

    /// Frames complete so far; with `finished`, also the plant's ticks that have no
    /// telemetry (the controller was lost): recorded from the truth alone.
    pub fn drain(&mut self, finished: bool, mut out: impl FnMut(Frame)) {
        loop {
            match (self.telemetry.front(), self.truth.front()) {
                (Some(a), Some(b)) if a.seq == b.seq => {
                    out(Frame::join(a, b));
                    self.telemetry.pop_front();
                    self.truth.pop_front();
                }
                (Some(a), Some(b)) if a.seq < b.seq => {
                    self.telemetry.pop_front();
                }
                (_, Some(b)) if finished || self.telemetry.front().is_some() => {
                    let t = Telemetry {
                        seq: b.seq,
                        time_s: b.time_s,
                        flags: daq_io::flags::NO_TELEMETRY,
                        ..Default::default()
                    };
                    out(Frame::join(&t, b));
                    self.truth_only += 1;
                    self.truth.pop_front();
                }
                _ => return,
            }
        }
    }
}

impl Joiner {
    /// The next truth tick expected (ticks of truth taken so far).
    pub fn next_truth(&self) -> u64 {
        self.next_truth
    }

    /// Ticks taken from both streams (what a lockstep plant paces on).
    pub fn taken(&self) -> u64 {
        self.next_truth.min(self.next_telemetry)
    }

    /// Records the transport lost (sequence gaps in either stream).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Blocks refused (counted, the first named).
    pub fn bad_blocks(&self) -> &BadBlocks {
        &self.bad
    }

    /// The run joined: the first block's run identity ([`daq_io::Sensor::run_id`]).
    pub fn run_id(&self) -> Option<u64> {
        self.run_id
    }

    /// Frames made from the truth alone ([`daq_io::flags::NO_TELEMETRY`]).
    pub fn truth_only(&self) -> u64 {
        self.truth_only
    }

    /// Whether the run is over: the plant's last truth block is in, and the controller's last
    /// telemetry block too — or the plant faulted, and a plant that lost its controller ends
    /// the run alone. (A lost plant ends it by silence, which only the caller can see.)
    pub fn run_over(&self) -> bool {
        self.truth_end && (self.telemetry_end || self.plant_faults != 0)
    }

    /// The plant's fault bits ([`flags::PLANT_FAULTS`]) seen so far.
    pub fn plant_faults(&self) -> u32 {
        self.plant_faults
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use daq_io::contract::RecordBlock;

    fn telemetry(index: u64, run: u64, seqs: std::ops::Range<u64>) -> TelemetryBlock {
        let mut b = TelemetryBlock::default();
        for seq in seqs {
            b.push(Telemetry {
                seq,
                ..Default::default()
            });
        }
        b.seal(index, 0, run);
        b
    }

    fn truth(index: u64, run: u64, seqs: std::ops::Range<u64>, end: bool) -> TruthBlock {
        let mut b = TruthBlock::default();
        for seq in seqs {
            b.push(Truth {
                seq,
                time_s: seq as f64 * 1e-6,
                ..Default::default()
            });
        }
        b.seal(index, if end { flags::END } else { 0 }, run);
        b
    }

    /// A count above capacity, ticks going backwards and another run's block are each refused,
    /// counted and named; every valid tick around them is joined.
    #[test]
    fn impossible_and_foreign_blocks_are_skipped_and_counted() {
        let mut j = Joiner::default();
        j.truth(&truth(0, 7, 0..64, false));
        j.telemetry(&telemetry(0, 7, 0..64));
        let mut over = telemetry(1, 7, 64..128);
        over.count = 1_000;
        j.telemetry(&over);
        j.telemetry(&telemetry(1, 7, 64..128));
        j.telemetry(&telemetry(2, 7, 0..10)); // backwards
        j.truth(&truth(1, 8, 64..128, true)); // another run's
        j.truth(&truth(1, 7, 64..128, false));
        let mut end = telemetry(3, 7, 128..130);
        end.flags = flags::END;
        j.telemetry(&end);
        j.truth(&truth(2, 7, 128..130, true));
        assert!(j.run_over());
        let mut frames = Vec::new();
        j.drain(true, |f| frames.push(f));
        assert_eq!(frames.len(), 130);
        // Tick k at k µs, each with its telemetry.
        assert!(frames
            .iter()
            .enumerate()
            .all(|(k, f)| f.time_ns == 1_000 * k as u64
                && f.telemetry.flags as u32 & flags::NO_TELEMETRY == 0));
        assert_eq!(j.truth_only(), 0);
        assert_eq!(j.dropped(), 0);
        let bad = j.bad_blocks();
        assert_eq!(bad.count, 3);
        assert_eq!(
            bad.first.as_deref(),
            Some("telemetry block 1 says it holds 1000 records, above its capacity of 64")
        );
        assert_eq!(j.run_id(), Some(7));
    }
}
