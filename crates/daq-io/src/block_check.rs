//! Record blocks as a receiver takes them: nothing a peer sends is taken on trust. A block's
//! count must be within its capacity and its ticks must go forward — within the block and after
//! the last record taken from the stream. A bad block (a same-user process publishing into the
//! run, or a DAQ daemon's bug) is refused whole, with why; the stream goes on from the last
//! good record, so no valid record is lost.

use crate::contract::{RecordBlock, BLOCK_TICKS};

/// Why a received block was set aside.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BadBlock {
    /// `count` above [`BLOCK_TICKS`].
    CountAboveCapacity {
        /// The block's index.
        block: u64,
        /// Its count.
        count: u32,
    },
    /// A record whose tick is not after the one before it (in the block, or the last record
    /// taken from the stream).
    SequenceBackwards {
        /// The block's index.
        block: u64,
        /// The record's tick.
        seq: u64,
        /// The tick it should have followed.
        after: u64,
    },
}

impl core::fmt::Display for BadBlock {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            BadBlock::CountAboveCapacity { block, count } => write!(
                f,
                "block {block} says it holds {count} records, above its capacity of {BLOCK_TICKS}"
            ),
            BadBlock::SequenceBackwards { block, seq, after } => write!(
                f,
                "block {block} holds tick {seq} after tick {after} (ticks must go forward)"
            ),
        }
    }
}

/// Takes the blocks of one record stream, checking each before any of its records is used.
#[derive(Debug, Clone, Copy, Default)]
pub struct BlockCheck {
    last: Option<u64>,
}

impl BlockCheck {
    /// The records of `b`, or why the block is refused (the stream's state is then unchanged).
    pub fn check<'a, B: RecordBlock>(&mut self, b: &'a B) -> Result<&'a [B::Record], BadBlock> {
        let records = b.records().ok_or(BadBlock::CountAboveCapacity {
            block: b.index(),
            count: b.count(),
        })?;
        let mut last = self.last;
        for r in records {
            let seq = B::seq(r);
            if let Some(after) = last.filter(|&after| seq <= after) {
                return Err(BadBlock::SequenceBackwards {
                    block: b.index(),
                    seq,
                    after,
                });
            }
            last = Some(seq);
        }
        self.last = last;
        Ok(records)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contract::{Telemetry, TelemetryBlock};

    fn block(index: u64, seqs: impl IntoIterator<Item = u64>) -> TelemetryBlock {
        let mut b = TelemetryBlock::default();
        for seq in seqs {
            b.push(Telemetry {
                seq,
                ..Default::default()
            });
        }
        b.seal(index, 0, 1);
        b
    }

    #[test]
    fn a_count_above_capacity_is_refused_not_sliced() {
        let mut check = BlockCheck::default();
        let mut b = block(3, 0..4);
        b.count = BLOCK_TICKS as u32 + 1;
        assert_eq!(
            check.check(&b),
            Err(BadBlock::CountAboveCapacity {
                block: 3,
                count: 65
            })
        );
        b.count = u32::MAX;
        assert!(check.check(&b).is_err());
        // The stream is unchanged: the first good block is taken whole.
        assert_eq!(check.check(&block(4, 0..64)).unwrap().len(), 64);
    }

    #[test]
    fn ticks_must_go_forward_within_and_across_blocks() {
        let mut check = BlockCheck::default();
        assert_eq!(check.check(&block(0, 0..64)).unwrap().len(), 64);
        // A repeat of the first block: backwards from the last record taken.
        assert_eq!(
            check.check(&block(1, 0..64)),
            Err(BadBlock::SequenceBackwards {
                block: 1,
                seq: 0,
                after: 63
            })
        );
        // Backwards inside a block.
        let e = check.check(&block(2, [64, 65, 65])).unwrap_err();
        assert_eq!(
            e,
            BadBlock::SequenceBackwards {
                block: 2,
                seq: 65,
                after: 65
            }
        );
        assert!(e.to_string().contains("tick 65 after tick 65"), "{e}");
        // Gaps are not faults (lost blocks are counted by their consumer).
        assert_eq!(check.check(&block(3, [64, 70, 71])).unwrap().len(), 3);
        assert_eq!(check.check(&block(4, [])).unwrap().len(), 0);
    }
}
