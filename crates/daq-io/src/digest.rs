//! A fingerprint of a closed loop, tick by tick: two loops that read the same samples and gave
//! the same commands have the same digest. FNV-1a (64-bit) over, per tick, the sample's `seq`,
//! `gap_v` and `accel_v` and the command's `dac_v`, each little-endian — simple enough to write
//! again in any language (the C and C++ examples do, and so does the Python test), which is the
//! point: `servo run --digest`, a C daemon and a Python loop compare loops across languages.

use crate::contract::{Command, Sensor};

/// The FNV-1a offset basis.
const BASIS: u64 = 0xcbf2_9ce4_8422_2325;
/// The FNV-1a prime.
const PRIME: u64 = 0x0000_0100_0000_01b3;

/// The digest of a loop so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoopDigest(u64);

impl Default for LoopDigest {
    fn default() -> Self {
        LoopDigest(BASIS)
    }
}

impl LoopDigest {
    /// Adds one tick: the sample the loop read and the command it gave.
    #[inline]
    pub fn add(&mut self, sample: &Sensor, command: &Command) {
        for word in [
            sample.seq,
            sample.gap_v.to_bits(),
            sample.accel_v.to_bits(),
            command.dac_v.to_bits(),
        ] {
            for byte in word.to_le_bytes() {
                self.0 = (self.0 ^ u64::from(byte)).wrapping_mul(PRIME);
            }
        }
    }

    /// The digest, as a number.
    pub fn value(&self) -> u64 {
        self.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a_of_the_words_in_order() {
        // FNV-1a of nothing is its basis; of one tick, the fold written out by hand.
        assert_eq!(LoopDigest::default().value(), BASIS);
        let s = Sensor {
            seq: 1,
            gap_v: 0.5,
            accel_v: -0.25,
            ..Default::default()
        };
        let c = Command {
            dac_v: 2.0,
            ..Default::default()
        };
        let mut d = LoopDigest::default();
        d.add(&s, &c);
        let mut h = BASIS;
        for w in [
            1u64,
            0.5f64.to_bits(),
            (-0.25f64).to_bits(),
            2.0f64.to_bits(),
        ] {
            for b in w.to_le_bytes() {
                h = (h ^ b as u64).wrapping_mul(PRIME);
            }
        }
        assert_eq!(d.value(), h);
        // Order matters: the same ticks the other way round differ.
        let mut e = LoopDigest::default();
        e.add(&Sensor { seq: 2, ..s }, &c);
        e.add(&s, &c);
        let mut f = LoopDigest::default();
        f.add(&s, &c);
        f.add(&Sensor { seq: 2, ..s }, &c);
        assert_ne!(e, f);
    }
}
