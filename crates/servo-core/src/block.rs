//! The one contract every servo-core block follows.

/// A signal block run once per servo tick.
///
/// Coefficients are built once from a configuration in physical units
/// (`Config::try_build(sample_period_s)`); `update` never validates, never allocates and never
/// panics. A non-finite input or state drives the output to zero and latches a fault that only
/// [`Block::reset`] clears.
///
/// ```
/// use servo_core::{Block, PidConfig};
/// let mut pid = PidConfig { kp: 2.0, ki: 0.0, kd: 0.0, ..PidConfig::THESIS_CH7 }
///     .try_build(5e-6)
///     .unwrap();
/// assert_eq!(pid.update(0.5), 1.0);
/// assert_eq!(pid.update(f64::NAN), 0.0);
/// assert!(pid.faulted());
/// pid.reset();
/// assert!(!pid.faulted());
/// ```
pub trait Block {
    /// What the block consumes each tick.
    type Input;
    /// What the block produces each tick.
    type Output;

    /// Advances one sample period and returns the new output.
    fn update(&mut self, input: Self::Input) -> Self::Output;

    /// Clears the state and the fault latch; coefficients are kept.
    fn reset(&mut self);

    /// Whether a non-finite input or state was seen since the last reset.
    fn faulted(&self) -> bool;
}

/// Latches the first non-finite value seen; shared by all blocks.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct FaultLatch(bool);

impl FaultLatch {
    /// No fault seen.
    pub(crate) const CLEAR: FaultLatch = FaultLatch(false);

    /// Latches when `x` is not finite; returns whether the latch is set.
    #[inline]
    pub(crate) fn check(&mut self, x: f64) -> bool {
        self.0 |= !x.is_finite();
        self.0
    }

    /// Latches when any of `xs` is not finite; returns whether the latch is set.
    #[inline]
    pub(crate) fn check_all(&mut self, xs: &[f64]) -> bool {
        // Summing propagates NaN and inf (inf − inf = NaN) without a branch per element.
        let probe = xs.iter().fold(0.0, |acc, x| acc + x * 0.0);
        self.check(probe)
    }

    /// Latches unconditionally (a fault the block detected itself).
    #[inline]
    pub(crate) fn set(&mut self) {
        self.0 = true;
    }

    /// Whether the latch is set.
    #[inline]
    pub(crate) fn is_set(&self) -> bool {
        self.0
    }
}
