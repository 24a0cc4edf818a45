//! An FIR feedforward at run time: fixed taps over a ring of the trajectory's past, the
//! newest entry `preview` ticks ahead of this tick. No allocation, no branches on the data: one
//! multiply-add per tap each tick.

use crate::preview::Window;
use servo_config::{FirSpec, MAX_FIR_SPAN};

// A power of two: indices wrap with a mask.
const _: () = assert!(MAX_FIR_SPAN.is_power_of_two());

/// The filter and the trajectory it reads.
#[derive(Debug, Clone)]
pub(crate) struct Fir {
    spec: FirSpec,
    /// `y_d[k + preview − j]` at `(newest − j) mod MAX_FIR_SPAN` (smoothed as the window is).
    history: [f64; MAX_FIR_SPAN],
    newest: usize,
    fault: bool,
}

impl Fir {
    /// The filter of `spec` (checked with its deployment).
    pub(crate) fn new(spec: &FirSpec) -> Self {
        Fir {
            spec: *spec,
            history: [0.0; MAX_FIR_SPAN],
            newest: 0,
            fault: false,
        }
    }

    /// Takes this tick's window: its newest smoothed sample joins the past.
    #[inline]
    pub(crate) fn follow(&mut self, w: &Window) {
        self.newest = (self.newest + 1) & (MAX_FIR_SPAN - 1);
        self.history[self.newest] = w.smooth(self.spec.preview as isize);
    }

    /// Fills the past from a window filled anew: what it holds, and before it the earliest
    /// sample it smooths (the trajectory at rest there).
    pub(crate) fn prime(&mut self, w: &Window) {
        let p = self.spec.preview as isize;
        self.newest = 0;
        for j in 0..MAX_FIR_SPAN {
            let at = (p - j as isize).max(-1);
            self.history[(MAX_FIR_SPAN - j) & (MAX_FIR_SPAN - 1)] = w.smooth(at);
        }
    }

    /// This tick's reference (m); 0 once a non-finite result has latched.
    #[inline]
    pub(crate) fn evaluate(&mut self) -> f64 {
        let mask = MAX_FIR_SPAN - 1;
        let mut r = 0.0;
        let mut at = self.newest;
        for &h in &self.spec.taps[..self.spec.taps_used] {
            r += h * self.history[at];
            at = at.wrapping_sub(self.spec.stride) & mask;
        }
        // A non-finite result latches and gives 0, as the ZPETC filter's sections do (the
        // loop trips on the latch this tick).
        self.fault |= !r.is_finite();
        if self.fault {
            0.0
        } else {
            r
        }
    }

    /// A non-finite result latched.
    pub(crate) fn faulted(&self) -> bool {
        self.fault
    }

    /// Clears the latch (the history follows the trajectory regardless).
    pub(crate) fn reset(&mut self) {
        self.fault = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use servo_config::MAX_FIR_TAPS;

    /// The filter is the convolution it states, `Σ taps[i]·y_d[k + preview − i·stride]`, the
    /// trajectory before its first sample at rest there; it follows the window every tick.
    #[test]
    fn the_filter_is_its_convolution() {
        let (preview, stride, used) = (5usize, 3usize, 20usize);
        let mut taps = [0.0; MAX_FIR_TAPS];
        for (i, t) in taps.iter_mut().take(used).enumerate() {
            *t = libm::sin(1.3 * i as f64) / (1.0 + i as f64);
        }
        let spec = FirSpec {
            taps,
            taps_used: used,
            preview,
            stride,
        };
        let y = |k: isize| libm::sin(0.05 * k.max(0) as f64) + 1e-3 * k.max(0) as f64;
        let mut w = Window::new(preview, 0).unwrap();
        let ahead: Vec<f64> = (0..=preview as isize).map(y).collect();
        w.prime(&ahead);
        let mut fir = Fir::new(&spec);
        fir.prime(&w);
        for k in 0..200isize {
            if k > 0 {
                w.push(y(k + preview as isize));
                fir.follow(&w);
            }
            let want: f64 = (0..used)
                .map(|i| taps[i] * y(k + preview as isize - (i * stride) as isize))
                .sum();
            assert!((fir.evaluate() - want).abs() < 1e-12, "tick {k}");
        }
        assert!(!fir.faulted());
        w.push(f64::NAN);
        fir.follow(&w);
        assert_eq!(fir.evaluate(), 0.0);
        assert!(fir.faulted());
    }
}
