//! Oversampling averager: `N` ADC conversions inside one servo tick → their mean (thesis
//! §4.4.3: 4 samples at 1 MHz averaged per servo sample). Averaging white converter noise over
//! `N` samples divides its variance by `N`.

use crate::block::{Block, FaultLatch};

/// Mean of `N` samples per tick.
///
/// ```
/// use servo_core::{Averager, Block};
/// let mut avg = Averager::<4>::new();
/// assert_eq!(avg.update([1.0, 2.0, 3.0, 6.0]), 3.0);
/// ```
#[derive(Debug, Clone, Copy, Default)]
pub struct Averager<const N: usize> {
    fault: FaultLatch,
}

impl<const N: usize> Averager<N> {
    const NONEMPTY: () = assert!(N > 0, "an averager needs at least one sample");

    /// An averager of `N ≥ 1` samples (checked at compile time).
    pub const fn new() -> Self {
        let () = Self::NONEMPTY;
        Averager {
            fault: FaultLatch::CLEAR,
        }
    }
}

impl<const N: usize> Block for Averager<N> {
    type Input = [f64; N];
    type Output = f64;

    #[inline]
    fn update(&mut self, x: [f64; N]) -> f64 {
        let mean = x.iter().sum::<f64>() / N as f64;
        if self.fault.check(mean) {
            return 0.0;
        }
        mean
    }

    fn reset(&mut self) {
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}
