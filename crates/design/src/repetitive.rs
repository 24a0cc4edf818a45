//! Convergence of repetitive control on the spindle angle (`servo_core::Repetitive`), checked
//! from the sampled loop before a run, and the learning filter's lead that makes it fastest.
//!
//! The table learns once per revolution; at harmonic `n` of the revolution (`n` cycles per
//! revolution, at `f = n·f_spindle` Hz) the error left after a revolution is the one before
//! times
//!
//! ```text
//! κ(n) = |Q(n)·(1 − k_r·H(n)·e^{j2πf·mT}·G(e^{j2πfT}))|
//! Q(n) = 1 − 2q₁(1 − cos 2πn/N),   H(n) = (3 + cos 2πn/N)/4
//! ```
//!
//! (Tomizuka, Tsao & Chew 1989, with the zero-phase `Q` over `N` bins; `H` is the bin average of
//! the linearly interpolated table; `G` the loop from the correction to the measured error,
//! `m` the lead in ticks). Learning converges when `κ < 1` at every harmonic the bins hold,
//! `0 ≤ n ≤ N/2`, at every speed the spindle may turn. Where `G` is known only within a disk of
//! radius `σ` (a measured loop), the check takes the worst over the disk:
//! `|Q|·(|1 − k_r·H·L·e^{jωm}·G| + k_r·|H·L|·σ)`.

use num_complex::Complex64 as C;
use std::f64::consts::TAU;

/// The learning law's parameters (`servo_core::RepetitiveConfig`'s, without the lead).
#[derive(Debug, Clone, PartialEq)]
pub struct Learning {
    /// Bins per revolution `N`.
    pub bins_per_rev: usize,
    /// Learning gain `k_r`.
    pub learning_gain: f64,
    /// Robustness filter's neighbour weight `q₁`.
    pub q_neighbour: f64,
    /// Learning filter taps at bin offsets `−K..=K` (odd length; `[1.0]`: the identity).
    pub filter: Vec<f64>,
}

impl Learning {
    /// `κ(n)` for the loop's response `g` at the harmonic's frequency with the lead applied.
    pub fn factor(&self, harmonic: usize, g_with_lead: C) -> f64 {
        self.factor_in_disk(harmonic, g_with_lead, 0.0)
    }

    /// The largest `κ(n)` for a loop response anywhere within `radius` of `g_with_lead`.
    pub fn factor_in_disk(&self, harmonic: usize, g_with_lead: C, radius: f64) -> f64 {
        let nu = TAU * harmonic as f64 / self.bins_per_rev as f64;
        let cos = libm::cos(nu);
        let q = 1.0 - 2.0 * self.q_neighbour * (1.0 - cos);
        let h = 0.25 * (3.0 + cos);
        let l = filter_response(&self.filter, nu);
        let k = self.learning_gain * h * l;
        q.abs() * ((1.0 - k * g_with_lead).norm() + k.norm() * radius)
    }
}

/// `L(ν) = Σ L_l·e^{jνl}` of taps at offsets `−K..=K`.
fn filter_response(taps: &[f64], nu: f64) -> C {
    let k = (taps.len() / 2) as f64;
    taps.iter()
        .enumerate()
        .map(|(i, &t)| t * C::from_polar(1.0, nu * (i as f64 - k)))
        .sum()
}

/// The loop sampled at every harmonic the bins hold, at each spindle speed.
#[derive(Debug, Clone)]
pub struct Harmonics {
    /// `(harmonic n, frequency in Hz, G(e^{j2πfT}), the radius G is known within)`.
    points: Vec<(usize, f64, C, f64)>,
    period_s: f64,
}

impl Harmonics {
    /// `g(f_hz)` at `n·s` Hz for `n = 0..=N/2` and each speed `s` of `speeds_rev_per_s`
    /// (revolutions per s), servo period `period_s` (s). Harmonics at or above the Nyquist
    /// frequency are left out (the loop cannot act there; the bins cannot hold them unless the
    /// table is finer than the ticks, which `servo_core` refuses).
    pub fn sample(
        bins_per_rev: usize,
        speeds_rev_per_s: &[f64],
        period_s: f64,
        mut g: impl FnMut(f64) -> C,
    ) -> Self {
        Self::sample_within(bins_per_rev, speeds_rev_per_s, period_s, |f| (g(f), 0.0))
    }

    /// [`Harmonics::sample`] of a loop known within a disk: `g(f_hz)` gives the response and
    /// the radius it is known within (a measurement's uncertainty); the checks take the worst
    /// over each disk.
    pub fn sample_within(
        bins_per_rev: usize,
        speeds_rev_per_s: &[f64],
        period_s: f64,
        mut g: impl FnMut(f64) -> (C, f64),
    ) -> Self {
        let nyquist = 0.5 / period_s;
        let mut points = Vec::new();
        for &s in speeds_rev_per_s {
            for n in 0..=bins_per_rev / 2 {
                let f = n as f64 * s.abs();
                if f < nyquist {
                    let (response, radius) = g(f);
                    points.push((n, f, response, radius));
                }
            }
        }
        Harmonics { points, period_s }
    }

    /// The worst harmonic with lead `lead_ticks`.
    pub fn convergence(&self, learning: &Learning, lead_ticks: f64) -> Convergence {
        self.scored(learning, lead_ticks).0
    }

    /// The worst harmonic, and the sum of `κ²` over all (to rank leads whose worst is the same).
    fn scored(&self, learning: &Learning, lead_ticks: f64) -> (Convergence, f64) {
        let mut worst = Convergence {
            factor: 0.0,
            harmonic: 0,
            frequency_hz: 0.0,
            lead_ticks,
        };
        let mut sum = 0.0;
        for &(n, f, g, radius) in &self.points {
            let lead = C::from_polar(1.0, TAU * f * lead_ticks * self.period_s);
            let k = learning.factor_in_disk(n, g * lead, radius);
            sum += k * k;
            // A NaN response (a loop that cannot be evaluated there) is the worst.
            if k.is_nan() || k > worst.factor {
                worst = Convergence {
                    factor: k,
                    harmonic: n,
                    frequency_hz: f,
                    lead_ticks,
                };
            }
        }
        (worst, sum)
    }

    /// The lead in [0, `max_lead_ticks`] (to 0.05 tick) whose worst harmonic converges fastest
    /// (of leads as good there, the one fastest over all harmonics).
    pub fn best_lead(&self, learning: &Learning, max_lead_ticks: f64) -> Convergence {
        let better = |a: (Convergence, f64), b: (Convergence, f64)| {
            if (b.0.factor, b.1) < (a.0.factor, a.1) {
                b
            } else {
                a
            }
        };
        let mut best = self.scored(learning, 0.0);
        let mut m = 1.0;
        while m <= max_lead_ticks {
            best = better(best, self.scored(learning, m));
            m += 1.0;
        }
        let centre = best.0.lead_ticks;
        for i in -20..=20 {
            let m = centre + 0.05 * f64::from(i);
            if (0.0..=max_lead_ticks).contains(&m) {
                best = better(best, self.scored(learning, m));
            }
        }
        best.0
    }
}

impl Harmonics {
    /// The learning filter of `2·half + 1` taps that makes `L·H·G·e^{jωm}` closest to 1 over the
    /// harmonics (least squares weighted by `|Q|`, where learning acts; a ridge of 10⁻³ of the
    /// mean diagonal keeps the taps small where the loop gives little to fit): the inverse of
    /// the loop over the band the bins hold.
    pub fn fit_filter(&self, learning: &Learning, lead_ticks: f64, half: usize) -> Vec<f64> {
        let t = 2 * half + 1;
        let mut normal = nalgebra::DMatrix::<f64>::zeros(t, t);
        let mut rhs = nalgebra::DVector::<f64>::zeros(t);
        for &(n, f, g, _) in &self.points {
            let nu = TAU * n as f64 / learning.bins_per_rev as f64;
            let cos = libm::cos(nu);
            let w = (1.0 - 2.0 * learning.q_neighbour * (1.0 - cos)).abs();
            let lead = C::from_polar(1.0, TAU * f * lead_ticks * self.period_s);
            let base = 0.25 * (3.0 + cos) * g * lead;
            if !base.is_finite() {
                continue;
            }
            let a: Vec<C> = (0..t)
                .map(|i| base * C::from_polar(1.0, nu * (i as f64 - half as f64)))
                .collect();
            for i in 0..t {
                rhs[i] += w * a[i].re;
                for j in 0..t {
                    normal[(i, j)] += w * (a[i].re * a[j].re + a[i].im * a[j].im);
                }
            }
        }
        let ridge = 1e-3 * normal.trace() / t as f64;
        for i in 0..t {
            normal[(i, i)] += ridge;
        }
        match normal.cholesky() {
            Some(c) => c.solve(&rhs).iter().copied().collect(),
            None => {
                let mut identity = vec![0.0; t];
                identity[half] = 1.0;
                identity
            }
        }
    }
}

/// The slowest-converging harmonic of a repetitive controller on a loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Convergence {
    /// `κ` there: the error left after one revolution (learning diverges when ≥ 1).
    pub factor: f64,
    /// The harmonic, cycles per revolution.
    pub harmonic: usize,
    /// Its frequency in Hz.
    pub frequency_hz: f64,
    /// The lead it was computed with, ticks.
    pub lead_ticks: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A loop that is a pure delay of `d` ticks with exact gain: the lead `d` makes
    /// `κ = |Q·(1 − k_r·H)|`, largest at DC (`|1 − k_r|`), which the search finds.
    #[test]
    fn a_pure_delay_is_led_by_its_delay() {
        let t = 5e-6;
        let d = 7.0;
        let learning = Learning {
            bins_per_rev: 1000,
            learning_gain: 0.6,
            q_neighbour: 0.25,
            filter: vec![1.0],
        };
        let h = Harmonics::sample(1000, &[50.0], t, |f| C::from_polar(1.0, -TAU * f * d * t));
        let best = h.best_lead(&learning, 50.0);
        assert!((best.lead_ticks - d).abs() < 1e-9, "{best:?}");
        assert!((best.factor - 0.4).abs() < 1e-12, "{best:?}");
        // Without the lead and without Q the delay turns the correction against the error
        // near where its phase passes π (f = 1/(2dT), harmonic 286; H falls beyond, so the
        // worst is a little below): |1 + k_r·H| ≈ 1.42.
        let bare = Learning {
            q_neighbour: 0.0,
            ..learning
        };
        let none = h.convergence(&bare, 0.0);
        let turns = none.frequency_hz * d * t;
        assert!(
            none.factor > 1.4 && (0.4..=0.5).contains(&turns),
            "{none:?}"
        );
    }

    /// A loop whose gain falls with frequency (a first-order lag at 2 kHz, no delay): the lead
    /// cannot undo its magnitude, the fitted filter does — with `k_r = 1` its worst factor over
    /// the band the bins hold falls to nearly `|1 − k_r| = 0`.
    #[test]
    fn the_fitted_filter_inverts_the_loop() {
        let t = 5e-6;
        let learning = Learning {
            bins_per_rev: 1000,
            learning_gain: 1.0,
            q_neighbour: 0.25,
            filter: vec![1.0],
        };
        let lag = |f: f64| 1.0 / C::new(1.0, f / 2000.0);
        let h = Harmonics::sample(1000, &[10.0], t, lag);
        let lead_only = h.best_lead(&learning, 50.0);
        let taps = h.fit_filter(&learning, lead_only.lead_ticks, 8);
        let fitted = Learning {
            filter: taps,
            ..learning.clone()
        };
        let with_filter = h.convergence(&fitted, lead_only.lead_ticks);
        // Lead only, with k_r = 1: where |G| has fallen (0.67 at 2.2 kHz) a revolution leaves a
        // third of the error (0.28); the fitted filter inverts the lag: under 1 %.
        assert!(lead_only.factor > 0.2, "{lead_only:?}");
        assert!(
            with_filter.factor < 0.05 * lead_only.factor,
            "{with_filter:?} vs {lead_only:?}"
        );
        // At low harmonics it is a deadbeat law (k_r = 1): a revolution leaves almost nothing.
        let low = fitted.factor(
            10,
            lag(100.0) * C::from_polar(1.0, TAU * 100.0 * lead_only.lead_ticks * t),
        );
        assert!(low < 0.02, "{low}");
    }

    /// `Q` alone: with `k_r·H·G = 0` the factor is |Q| = |1 − 2q₁(1 − cos 2πn/N)|, which for
    /// q₁ > ¼ exceeds 1 at the bins' Nyquist harmonic (|1 − 4q₁|).
    #[test]
    fn q_beyond_a_quarter_amplifies_the_finest_harmonic() {
        let learning = Learning {
            bins_per_rev: 64,
            learning_gain: 1e-9,
            q_neighbour: 0.3,
            filter: vec![1.0],
        };
        assert!((learning.factor(32, C::new(0.0, 0.0)) - 0.2).abs() < 1e-12);
        let learning = Learning {
            q_neighbour: 0.6,
            ..learning
        };
        assert!((learning.factor(32, C::new(0.0, 0.0)) - 1.4).abs() < 1e-12);
    }

    /// Over a disk the check is the worst point of it: a loop known within 0.3 of its value
    /// at a harmonic where the centre converges may not.
    #[test]
    fn the_disk_is_judged_by_its_worst_point() {
        let learning = Learning {
            bins_per_rev: 100,
            learning_gain: 1.0,
            q_neighbour: 0.0,
            filter: vec![1.0],
        };
        let g = C::new(0.5, 0.0);
        let centre = learning.factor(0, g);
        assert!((centre - 0.5).abs() < 1e-12);
        // The worst of |1 − (g + δ)| over |δ| ≤ 0.3 is at δ = −0.3: 0.8; over 0.6: 1.1.
        assert!((learning.factor_in_disk(0, g, 0.3) - 0.8).abs() < 1e-12);
        let h = Harmonics::sample_within(100, &[10.0], 1e-4, |_| (g, 0.6));
        let c = h.convergence(&learning, 0.0);
        assert!((c.factor - 1.1).abs() < 1e-12, "{c:?}");
    }
}
