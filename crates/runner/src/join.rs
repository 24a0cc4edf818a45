//! Joins a run's two record streams — the controller's telemetry and the plant's truth, as
//! they arrive in blocks over shared memory — into frames, tick by tick (the recorder's and
//! the live view's input). A tick whose telemetry was lost is kept from the truth alone and
//! flagged [`daq_io::flags::NO_TELEMETRY`]; sequence gaps are counted; the blocks' flags say
//! when the run is over.

use daq_io::{flags, Telemetry, TelemetryBlock, Truth, TruthBlock};
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
}

impl Joiner {
    /// Takes the telemetry records of one block.
    pub fn telemetry(&mut self, b: &TelemetryBlock) {
        self.telemetry_end |= b.flags & flags::END != 0;
        for r in &b.ticks[..b.count as usize] {
            self.dropped += r.seq.saturating_sub(self.next_telemetry);
            self.next_telemetry = r.seq + 1;
            self.telemetry.push_back(*r);
        }
    }

    /// Takes the truth records of one block.
    pub fn truth(&mut self, b: &TruthBlock) {
        self.truth_end |= b.flags & flags::END != 0;
        self.plant_faults |= b.flags & flags::PLANT_FAULTS;
        for r in &b.ticks[..b.count as usize] {
            self.dropped += r.seq.saturating_sub(self.next_truth);
            self.next_truth = r.seq + 1;
            self.truth.push_back(*r);
        }
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
