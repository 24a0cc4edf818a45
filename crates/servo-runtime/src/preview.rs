//! The previewed desired trajectory of a servo tick: a sliding window from the past to
//! `preview` ticks ahead, and its zero-phase smoothing by a Hann window (for trajectories with
//! kinks or steps — beam-integrator cell edges, image pixels — that no loop can follow and
//! whose inverse would saturate the actuator). Fixed capacity: the tick never allocates.

use servo_config::{hann_weights, MAX_PREVIEW};

/// The longest window: the past a smoothing needs, now, and the preview.
const LEN: usize = 2 * MAX_PREVIEW + 2;

/// The ring's storage: room for the longest window twice, a power of two so that an index
/// masked with `RING - 1` needs no bounds check.
const RING: usize = (2 * LEN).next_power_of_two();

/// `y_d[k + j]` for `j ∈ −past..=preview`, with Hann weights for smoothing.
///
/// A ring written twice (at `i` and `i + len`), so the window is always the contiguous
/// `y[start..start + len]`: a tick writes two values instead of sliding the window.
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct Window {
    /// Where the window's oldest value sits (`0..len`).
    start: usize,
    /// The window's length, `past + preview + 1`.
    len: usize,
    past: usize,
    preview: usize,
    half: usize,
    /// Normalised Hann weights `w[|i|]`, `i ∈ −half..=half`.
    weights: [f64; MAX_PREVIEW + 1],
    y: [f64; RING],
}

impl Window {
    /// No window yet: storage for [`Window::reset`].
    pub(crate) const EMPTY: Window = Window {
        y: [0.0; RING],
        start: 0,
        len: 1,
        past: 0,
        preview: 0,
        weights: [0.0; MAX_PREVIEW + 1],
        half: 0,
    };

    /// A window for a feedforward needing `lead` ticks of preview, smoothed over `2·half + 1`
    /// ticks (0: none). None when the preview would exceed [`MAX_PREVIEW`].
    #[cfg(test)]
    pub(crate) fn new(lead: usize, half: usize) -> Option<Self> {
        let mut w = Window::EMPTY;
        w.reset(lead, half).then_some(w)
    }

    /// [`Window::new`] in place: false, `self` untouched, when the preview would exceed
    /// [`MAX_PREVIEW`].
    pub(crate) fn reset(&mut self, lead: usize, half: usize) -> bool {
        let preview = lead + half;
        if preview > MAX_PREVIEW {
            return false;
        }
        self.weights = hann_weights(half);
        self.y.fill(0.0);
        let past = half + 1;
        (self.start, self.len, self.past) = (0, past + preview + 1, past);
        (self.preview, self.half) = (preview, half);
        true
    }

    /// Ticks of preview the window needs.
    pub(crate) fn preview(&self) -> usize {
        self.preview
    }

    /// Fills the window at the first tick: `fill` writes `ahead[j] = y_d[j]` for
    /// `j = 0..=preview` into the slice it is given; the past is taken as at rest at `y_d[0]`.
    pub(crate) fn prime(&mut self, fill: impl FnOnce(&mut [f64])) {
        let (past, len) = (self.past, self.len);
        self.start = 0;
        fill(&mut self.y[past..len]);
        let now = self.y[past];
        self.y[..past].fill(now);
        for i in 0..len {
            self.y[(i + len) & (RING - 1)] = self.y[i & (RING - 1)];
        }
    }

    /// Slides by one tick with `y_d[k + preview]`.
    #[inline]
    pub(crate) fn push(&mut self, ahead: f64) {
        let (start, len) = (self.start, self.len);
        // The oldest value's two places take the newest: the window moves one on.
        self.y[start & (RING - 1)] = ahead;
        self.y[(start + len) & (RING - 1)] = ahead;
        self.start = if start + 1 == len { 0 } else { start + 1 };
    }

    /// `y_d[k + j]`.
    #[inline]
    pub(crate) fn at(&self, j: isize) -> f64 {
        self.y[(self.start + self.past).wrapping_add_signed(j) & (RING - 1)]
    }

    /// The smoothed trajectory at `k + j` (needs `|j| + half` inside the window).
    #[inline]
    pub(crate) fn smooth(&self, j: isize) -> f64 {
        let h = self.half as isize;
        let mut acc = self.weights[0] * self.at(j);
        for i in 1..=h {
            acc += self.weights[i as usize] * (self.at(j - i) + self.at(j + i));
        }
        acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hann_smoothing_keeps_lines_and_has_unit_gain() {
        let mut w = Window::new(1, 10).unwrap();
        w.prime(|ahead| {
            ahead
                .iter_mut()
                .enumerate()
                .for_each(|(j, v)| *v = j as f64)
        });
        for k in 1..=30 {
            w.push((w.preview() + k) as f64);
        }
        // After 30 pushes y_d[k + j] = 30 + j: a straight line is unchanged by a symmetric
        // window with unit sum.
        for j in -1..=1 {
            assert!((w.smooth(j) - (30.0 + j as f64)).abs() < 1e-12);
        }
        assert_eq!(w.at(0), 30.0);
    }

    #[test]
    fn preview_beyond_capacity_is_refused() {
        assert!(Window::new(3, MAX_PREVIEW - 2).is_none());
        assert!(Window::new(2, MAX_PREVIEW - 2).is_some());
    }
}
