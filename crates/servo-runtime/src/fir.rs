//! An FIR feedforward at run time: fixed taps over the trajectory's past, the newest entry
//! `preview` ticks ahead of this tick. The past is kept by phase: taps `stride` ticks apart
//! read one row (the ticks of this tick's phase), newest first, contiguously — multiply-adds
//! in fours, no index arithmetic. No allocation; the same work every tick.

use crate::preview::Window;
use servo_config::{FirSpec, MAX_FIR_SPAN, MAX_FIR_TAPS};

/// The filter and the trajectory it reads.
#[derive(Debug, Clone)]
pub(crate) struct Fir {
    spec: FirSpec,
    /// `rest[i]`: the sum of the taps from `i` on (what the taps that reach back before the
    /// window was filled multiply: the trajectory at rest there).
    rest: [f64; MAX_FIR_TAPS + 1],
    /// Row `phase` (of `stride` rows, `taps_used` long each) holds the ticks of that phase,
    /// a ring whose newest entry is at column `column`, older ones after it.
    history: [f64; MAX_FIR_SPAN],
    phase: usize,
    column: usize,
    /// Entries followed since the window was filled (saturating).
    known: usize,
    /// The trajectory at rest before the window was filled.
    at_rest: f64,
    fault: bool,
}

impl Fir {
    /// No filter: storage for [`Fir::load`].
    pub(crate) const EMPTY: Fir = Fir {
        spec: FirSpec {
            taps: [0.0; MAX_FIR_TAPS],
            taps_used: 0,
            preview: 0,
            stride: 1,
        },
        rest: [0.0; MAX_FIR_TAPS + 1],
        history: [0.0; MAX_FIR_SPAN],
        phase: 0,
        column: 0,
        known: 0,
        at_rest: 0.0,
        fault: false,
    };

    /// The filter of `spec` (checked with its deployment: `taps_used·stride` ≤
    /// [`MAX_FIR_SPAN`]), written in place: its past is filled when the window is
    /// ([`Fir::prime`]).
    pub(crate) fn load(&mut self, spec: &FirSpec) {
        self.spec = *spec;
        self.rest[MAX_FIR_TAPS] = 0.0;
        for i in (0..MAX_FIR_TAPS).rev() {
            let tap = if i < spec.taps_used {
                spec.taps[i]
            } else {
                0.0
            };
            self.rest[i] = self.rest[i + 1] + tap;
        }
        self.history.fill(0.0);
        (self.phase, self.column, self.known) = (0, 0, 0);
        (self.at_rest, self.fault) = (0.0, false);
    }

    /// One more entry of the past.
    #[inline]
    fn push(&mut self, y: f64) {
        self.phase += 1;
        if self.phase == self.spec.stride {
            self.phase = 0;
            self.column = match self.column {
                0 => self.spec.taps_used - 1,
                c => c - 1,
            };
        }
        self.history[self.phase * self.spec.taps_used + self.column] = y;
        self.known = (self.known + 1).min(MAX_FIR_SPAN);
    }

    /// Takes this tick's window: its newest smoothed sample joins the past.
    #[inline]
    pub(crate) fn follow(&mut self, w: &Window) {
        self.push(w.smooth(self.spec.preview as isize));
    }

    /// Starts from a window filled anew (the first tick, or ticks skipped): what it holds from
    /// the tick before this one to the preview, and before that the trajectory at rest at the
    /// earliest sample it smooths. A few dozen stores: this runs on a tick.
    pub(crate) fn prime(&mut self, w: &Window) {
        let p = self.spec.preview as isize;
        (self.phase, self.column, self.known) = (self.spec.stride - 1, 0, 0);
        for j in -1..=p {
            self.push(w.smooth(j));
        }
        self.at_rest = w.smooth(-1);
    }

    /// This tick's reference (m); 0 once a non-finite result has latched.
    #[inline]
    pub(crate) fn evaluate(&mut self) -> f64 {
        let n = self.spec.taps_used;
        // Taps that reach back into what was followed; the others see the trajectory at rest.
        let reach = (self.known - 1) / self.spec.stride + 1;
        let reach = reach.min(n);
        let row = &self.history[self.phase * n..(self.phase + 1) * n];
        let (older, newer) = row.split_at(self.column);
        let taps = &self.spec.taps[..reach];
        let (first, second) = taps.split_at(newer.len().min(reach));
        let r = self.rest[reach] * self.at_rest + dot(first, newer) + dot(second, older);
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

/// `Σ a[i]·b[i]` over the shorter of the two, in four running sums (the M7's FPU pipelines
/// them).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let whole = n - n % 4;
    let mut acc = [0.0; 4];
    for (x, y) in a[..whole].chunks_exact(4).zip(b[..whole].chunks_exact(4)) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for (x, y) in a[whole..n].iter().zip(&b[whole..n]) {
        sum += x * y;
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The filter is the convolution it states, `Σ taps[i]·y_d[k + preview − i·stride]`, the
    /// trajectory before its first sample at rest there; it follows the window every tick, across
    /// the ring's wrap.
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
        w.prime(|ahead| {
            for (j, v) in ahead.iter_mut().enumerate() {
                *v = y(j as isize);
            }
        });
        let mut fir = Fir::EMPTY;
        fir.load(&spec);
        fir.prime(&w);
        for k in 0..2600isize {
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
