//! A coloured noise on one reading, sampled once per tick, as a discrete process in
//! innovations form: the shape the closed loop, the budget, the spectrum overlay and the H2
//! design take every coloured source in (the averaged sensor noise, the averaged ADC
//! quantisation error).

use lti::StateSpace;
use nalgebra::DMatrix;

/// A per-tick process `n_k` as `ξ⁺ = a ξ + k e`, `n = c ξ + e`, with `e` white of per-tick
/// variance `variance` (unit², e.g. V²): its spectrum, and every variance a linear loop driven
/// by it has, are the process's own.
#[derive(Debug, Clone)]
pub struct SampledNoise {
    /// The innovations form as a discrete system per tick: `A = a` (n × n), `B = k`, `C = c`,
    /// `D = 1`, from `e` to `n_k`.
    pub sys: StateSpace,
    /// Innovation variance per tick (unit²).
    pub variance: f64,
}

/// Longest autocovariance (in ticks) [`SampledNoise::from_autocovariance`] realises.
pub const MAX_LAGS: usize = 64;

impl SampledNoise {
    pub(crate) fn innovations(
        a: DMatrix<f64>,
        k: DMatrix<f64>,
        c: DMatrix<f64>,
        variance: f64,
    ) -> Self {
        SampledNoise {
            sys: StateSpace {
                a,
                b: k,
                c,
                d: DMatrix::identity(1, 1),
            },
            variance,
        }
    }

    /// White noise of per-tick variance `variance` (no states).
    pub fn white(variance: f64) -> Self {
        let zero = |rows, cols| DMatrix::zeros(rows, cols);
        SampledNoise::innovations(zero(0, 0), zero(0, 1), zero(1, 0), variance)
    }

    /// The process whose autocovariance is `r[m]` at lag m ticks (`r[0]` its variance) and
    /// zero beyond the last (a moving average of order `r.len() − 1` ≤ [`MAX_LAGS`]): the
    /// minimum-phase spectral factor, found by running the innovations recursion of the
    /// shift-register realisation (`A` shifts up, `C = e₁ᵀ`, `E[x_{k+1} n_k] = r[1..]`)
    /// to its fixed point
    /// `Σ = AΣAᵀ + (G − AΣCᵀ)(r₀ − CΣCᵀ)⁻¹(G − AΣCᵀ)ᵀ`, `k = (G − AΣCᵀ)/(r₀ − CΣCᵀ)`.
    /// None when `r` is no autocovariance of a stationary process (its spectrum goes negative
    /// somewhere) or is longer than [`MAX_LAGS`] + 1.
    pub fn from_autocovariance(r: &[f64]) -> Option<Self> {
        let m = r.len().checked_sub(1)?;
        if m > MAX_LAGS || r.iter().any(|x| !x.is_finite()) || r[0] <= 0.0 {
            return None;
        }
        if m == 0 {
            return Some(SampledNoise::white(r[0]));
        }
        let shift = DMatrix::from_fn(m, m, |i, j| if j == i + 1 { 1.0 } else { 0.0 });
        let g = DMatrix::from_column_slice(m, 1, &r[1..]);
        let mut sigma = DMatrix::<f64>::zeros(m, m);
        // Each step adds the next innovation's share; the distance to the fixed point falls
        // as the factor's largest zero to the power 2·steps.
        for _ in 0..10_000 {
            let v = r[0] - sigma[(0, 0)];
            if v.is_nan() || v <= 0.0 {
                return None;
            }
            let gain = (&g - &shift * sigma.columns(0, 1)) / v;
            let next = &shift * &sigma * shift.transpose() + &gain * gain.transpose() * v;
            let change = (&next - &sigma).amax();
            sigma = next;
            if change <= 1e-15 * r[0] {
                let v = r[0] - sigma[(0, 0)];
                let k = (&g - &shift * sigma.columns(0, 1)) / v;
                let c = DMatrix::from_fn(1, m, |_, j| if j == 0 { 1.0 } else { 0.0 });
                return Some(SampledNoise::innovations(shift, k, c, v));
            }
        }
        None
    }

    /// Its states.
    pub fn states(&self) -> usize {
        self.sys.nx()
    }

    /// Its variance per tick (unit²): `c Σ cᵀ + variance`, Σ the stationary state covariance.
    pub fn total_variance(&self) -> f64 {
        if self.states() == 0 {
            return self.variance;
        }
        let k = &self.sys.b;
        lti::dlyap(&self.sys.a, &(k * k.transpose() * self.variance)).map_or(f64::NAN, |(p, _)| {
            (&self.sys.c * p * self.sys.c.transpose())[(0, 0)] + self.variance
        })
    }

    /// Adds this noise to the reading in row `reading` of a discrete system `(a, b)` whose
    /// states from `at` on are the noise's own, driven by input column `input` carrying the
    /// innovation scaled by `scale`: `reading⁺ += c ξ + scale·e`, `ξ⁺ = a ξ + k·scale·e`.
    pub fn place(
        &self,
        a: &mut DMatrix<f64>,
        b: &mut DMatrix<f64>,
        (reading, at, input): (usize, usize, usize),
        scale: f64,
    ) {
        let (n, s) = (self.states(), &self.sys);
        a.view_mut((reading, at), (1, n)).copy_from(&s.c);
        a.view_mut((at, at), (n, n)).copy_from(&s.a);
        b.view_mut((at, input), (n, 1)).copy_from(&(&s.b * scale));
        b[(reading, input)] = scale;
    }

    /// One-sided PSD at `f_hz` for a tick of `period_s`, unit²/Hz.
    pub fn psd(&self, f_hz: f64, period_s: f64) -> f64 {
        if self.states() == 0 {
            return 2.0 * self.variance * period_s;
        }
        // H(e^{j2πfT}) = 1 + c (zI − a)⁻¹ k; the process is stable, so z is never a pole.
        self.sys
            .freq_response_discrete(f_hz, period_s)
            .map_or(f64::NAN, |h| {
                2.0 * self.variance * period_s * h[(0, 0)].norm_sqr()
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An MA(1) process `n = e_k + θ e_{k−1}` (|θ| < 1) is recovered from its autocovariance
    /// `[1 + θ², θ]`: the gain θ and unit innovations (the minimum-phase factor, not 1/θ).
    #[test]
    fn a_moving_average_is_recovered_from_its_autocovariance() {
        for theta in [0.3, -0.8, 0.95] {
            let s = SampledNoise::from_autocovariance(&[1.0 + theta * theta, theta]).unwrap();
            assert!(
                (s.sys.b[(0, 0)] - theta).abs() < 1e-6,
                "θ {theta}: {}",
                s.sys.b
            );
            assert!((s.variance - 1.0).abs() < 1e-6);
            assert!((s.total_variance() - (1.0 + theta * theta)).abs() < 1e-9);
        }
    }

    /// Of order 3: the realisation's autocovariance at lags 0..=4 is the one asked for (and 0
    /// beyond), and a sequence with a negative spectrum is refused.
    #[test]
    fn the_realisation_has_the_autocovariance_asked_for() {
        let r = [2.0, 0.9, 0.3, -0.1];
        let s = SampledNoise::from_autocovariance(&r).unwrap();
        let (a, k, c) = (&s.sys.a, &s.sys.b, &s.sys.c);
        // Impulse response h₀ = 1, h_j = c a^{j−1} k; r_m = v Σ_j h_j h_{j+m}.
        let mut h = vec![1.0];
        let mut x = k.clone();
        for _ in 0..8 {
            h.push((c * &x)[(0, 0)]);
            x = a * x;
        }
        for (m, want) in r.iter().chain([0.0].iter()).enumerate() {
            let got: f64 = (0..h.len() - m).map(|j| h[j] * h[j + m]).sum::<f64>() * s.variance;
            assert!((got - want).abs() < 1e-9, "lag {m}: {got} vs {want}");
        }
        assert!(SampledNoise::from_autocovariance(&[1.0, 0.9]).is_none());
    }
}
