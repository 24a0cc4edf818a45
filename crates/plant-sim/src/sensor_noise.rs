//! Capacitive-sensor noise as the electronics make it (thesis §4.5.2, eq 6-6): a flat noise
//! density `Ws` (one-sided, V/√Hz at the sensor output) band-limited by the sensor's own output
//! filter — the 2nd-order Butterworth of eq 5-8 at `capa.bandwidth_hz` — then by the
//! converter's first-order anti-aliasing stage when one is configured (`adc.anti_alias_hz`),
//! and sampled by every ADC conversion.
//!
//! The noise is a continuous process, so what one 1 MHz conversion sees does not depend on how
//! often the controller runs: its variance is `Ws²·ENBW` (ENBW = π/(2√2)·f_c for the
//! Butterworth alone) at every servo rate, and conversions 1 µs apart are nearly the same draw
//! (the band ends far below 1 MHz), so averaging four of them removes little of it. The process
//! is integrated exactly between conversion instants (transition `e^{AΔ}` and the Van Loan
//! covariance of the white input over `Δ`), one Gaussian draw per filter state per conversion.
//!
//! For analysis, [`SensorNoise::sampled`] is the averaged reading of one tick as a discrete
//! process in innovations form ([`SampledNoise`]: one white input, the same spectrum), which
//! the closed loop, the budget and the H2 design use.

#[cfg(feature = "linear")]
use crate::sampled_noise::SampledNoise;
use lti::expm;
use nalgebra::{DMatrix, SMatrix, SVector};
use std::f64::consts::{PI, SQRT_2};

/// Filter states kept in fixed-size storage: the Butterworth's two and the optional
/// anti-aliasing stage's one (unused states stay zero).
const MAX_STATES: usize = 3;
type Mat = SMatrix<f64, MAX_STATES, MAX_STATES>;
type Vect = SVector<f64, MAX_STATES>;

/// The band-limiting filter `ξ' = A ξ + b w`, `n = ξ[out]`: the Butterworth in states
/// `[n, ṅ/ω_c]`, then, for a non-zero `anti_alias_hz`, the first-order anti-aliasing stage.
fn filter(bandwidth_hz: f64, anti_alias_hz: f64) -> (DMatrix<f64>, DMatrix<f64>, usize) {
    let w = 2.0 * PI * bandwidth_hz;
    let n = if anti_alias_hz > 0.0 { 3 } else { 2 };
    let mut a = DMatrix::zeros(n, n);
    a[(0, 1)] = w;
    a[(1, 0)] = -w;
    a[(1, 1)] = -SQRT_2 * w;
    let mut b = DMatrix::zeros(n, 1);
    b[(1, 0)] = w;
    if n == 3 {
        let wa = 2.0 * PI * anti_alias_hz;
        a[(2, 0)] = wa;
        a[(2, 2)] = -wa;
    }
    // Read out the Butterworth's output, or the anti-aliasing stage's.
    (a, b, if n == 3 { 2 } else { 0 })
}

/// `m` in the top-left corner of a zero [`Mat`].
fn padded(m: &DMatrix<f64>) -> Mat {
    Mat::from_fn(|i, j| {
        if i < m.nrows() && j < m.ncols() {
            m[(i, j)]
        } else {
            0.0
        }
    })
}

/// One exact step of `Δ` seconds: the transition and a square root of the covariance the
/// white input adds over it (Van Loan), so that `ξ ← Φ ξ + L g` with `g` unit normals.
#[derive(Debug, Clone, Copy)]
struct Step {
    phi: Mat,
    root: Mat,
}

impl Step {
    fn new(a: &DMatrix<f64>, b: &DMatrix<f64>, intensity: f64, dt: f64) -> Step {
        // expm([[−A, Q], [0, Aᵀ]]·Δ) = [[·, F12], [0, F22]]: Φ = F22ᵀ, covariance = F22ᵀ·F12.
        let n = a.nrows();
        let q = b * b.transpose() * intensity;
        let mut m = DMatrix::zeros(2 * n, 2 * n);
        m.view_mut((0, 0), (n, n)).copy_from(&(-a * dt));
        m.view_mut((0, n), (n, n)).copy_from(&(q * dt));
        m.view_mut((n, n), (n, n)).copy_from(&(a.transpose() * dt));
        let e = expm(&m);
        let phi = e.view((n, n), (n, n)).transpose();
        let cov = &phi * e.view((0, n), (n, n));
        Step {
            phi: padded(&phi),
            // L = Rᵀ for cov = RᵀR (a zero-length step gives zero).
            root: padded(&lti::sqrt_factor(&cov).transpose()),
        }
    }
}

/// The sensor noise of one gap channel, stepped conversion by conversion (allocation free).
#[derive(Debug, Clone, Copy)]
pub struct SensorNoise {
    /// From the last conversion of a tick to the first of the next.
    between_ticks: Step,
    /// Between conversions inside a tick.
    between_conversions: Step,
    /// Filter states in use (2, or 3 with the anti-aliasing stage) and the one read out.
    states: usize,
    out: usize,
    /// The filter's continuous dynamics and the stationary covariance of its states, V².
    #[cfg(feature = "linear")]
    a: Mat,
    #[cfg(feature = "linear")]
    p: Mat,
    xi: Vect,
}

impl SensorNoise {
    /// Noise of density `density_v_per_rt_hz` (one-sided) band-limited at `bandwidth_hz`, then
    /// by a first-order anti-aliasing stage at `anti_alias_hz` (0: none), converted
    /// `oversampling` times per tick of `period_s` at `conversion_rate_hz` (the last
    /// conversion on the tick).
    pub fn new(
        density_v_per_rt_hz: f64,
        bandwidth_hz: f64,
        anti_alias_hz: f64,
        period_s: f64,
        oversampling: u32,
        conversion_rate_hz: f64,
    ) -> SensorNoise {
        let (a, b, out) = filter(bandwidth_hz, anti_alias_hz);
        let intensity = density_v_per_rt_hz * density_v_per_rt_hz / 2.0;
        let spacing = 1.0 / conversion_rate_hz;
        let gap = (period_s - (oversampling as f64 - 1.0) * spacing).max(0.0);
        SensorNoise {
            between_ticks: Step::new(&a, &b, intensity, gap),
            between_conversions: Step::new(&a, &b, intensity, spacing),
            states: a.nrows(),
            out,
            #[cfg(feature = "linear")]
            a: padded(&a),
            // Stationary covariance: A P + P Aᵀ + b bᵀ·intensity = 0.
            #[cfg(feature = "linear")]
            p: lti::riccati::lyap(&a, &(&b * b.transpose() * intensity))
                .map_or_else(|_| Mat::from_element(f64::NAN), |(p, _)| padded(&p)),
            xi: Vect::zeros(),
        }
    }

    /// Variance of the noise one conversion sees, V² (without the anti-aliasing stage
    /// `Ws²·π f_c/(2√2)`), whatever the rate.
    #[cfg(feature = "linear")]
    pub fn conversion_variance(&self) -> f64 {
        self.p[(self.out, self.out)]
    }

    /// Back to rest (the process starts at zero with the rest of the plant and is stationary
    /// within a millisecond).
    pub fn reset(&mut self) {
        self.xi = Vect::zeros();
    }

    /// The noise at the next conversion, V: the first of a tick when `first`, then the
    /// others 1/f_adc apart.
    #[inline]
    pub fn next(&mut self, first: bool, mut normal: impl FnMut() -> f64) -> f64 {
        let s = if first {
            &self.between_ticks
        } else {
            &self.between_conversions
        };
        let (g0, g1) = (normal(), normal());
        let g2 = if self.states > 2 { normal() } else { 0.0 };
        self.xi = s.phi * self.xi + s.root * Vect::new(g0, g1, g2);
        self.xi[self.out]
    }

    /// The averaged noise of one tick of `oversampling` conversions as a discrete process
    /// in innovations form.
    #[cfg(feature = "linear")]
    pub fn sampled(&self, oversampling: u32) -> SampledNoise {
        averaged(self, oversampling as usize)
    }

    /// Covariance of the noise at two instants `lag_s` seconds apart, V² (the conversion
    /// variance at 0): `cᵀ e^{A|τ|} P c`, P the stationary covariance of the filter states.
    #[cfg(feature = "linear")]
    pub fn lag_covariance(&self, lag_s: f64) -> f64 {
        let n = self.states;
        let a = DMatrix::from_fn(n, n, |i, j| self.a[(i, j)]);
        let p = DMatrix::from_fn(n, n, |i, j| self.p[(i, j)]);
        let phi = expm(&(a * lag_s.abs()));
        (phi * p)[(self.out, self.out)]
    }
}

/// The tick-averaged noise of `os` conversions as a discrete process in innovations form.
#[cfg(feature = "linear")]
fn averaged(noise: &SensorNoise, os: usize) -> SampledNoise {
    // Exact model with the n·os unit draws v of the tick: ξ_{k+1} = Φ ξ_k + B v,
    // n_k = C ξ_k + D v (the mean of the conversions' read-out state).
    let n = noise.states;
    let m = n * os;
    let to_d = |x: &Mat| DMatrix::from_fn(n, n, |i, j| x[(i, j)]);
    let (mut phi, mut bv) = (DMatrix::identity(n, n), DMatrix::zeros(n, m));
    let (mut c, mut d) = (DMatrix::zeros(1, n), DMatrix::zeros(1, m));
    for j in 0..os {
        let s = if j == 0 {
            &noise.between_ticks
        } else {
            &noise.between_conversions
        };
        phi = to_d(&s.phi) * phi;
        bv = to_d(&s.phi) * bv;
        bv.view_mut((0, n * j), (n, n)).copy_from(&to_d(&s.root));
        c += phi.rows(noise.out, 1) / os as f64;
        d += bv.rows(noise.out, 1) / os as f64;
    }
    // Steady-state Kalman predictor of n from its own past (the dual DARE). R = DDᵀ > 0 for
    // any positive density and Φ is stable, so it has a solution; should rounding defeat
    // it on extreme parameters, the noise is kept white with its exact per-tick variance.
    let q = &bv * bv.transpose();
    let r = &d * d.transpose();
    let s = &bv * d.transpose();
    match lti::riccati::dare(&phi.transpose(), &c.transpose(), &q, &r, Some(&s)) {
        Ok(ric) => {
            let p = &ric.x;
            let variance = (&c * p * c.transpose() + &r)[(0, 0)];
            let k = (&phi * p * c.transpose() + &s) / variance;
            SampledNoise::innovations(phi, k, c, variance)
        }
        Err(_) => {
            let (stationary, _) = lti::dlyap(&phi, &q).unwrap_or((DMatrix::zeros(n, n), 0.0));
            SampledNoise::white((&c * stationary * c.transpose() + &r)[(0, 0)])
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Per conversion the variance is the density times the filter's noise bandwidth,
    /// π/(2√2)·f_c for a 2nd-order Butterworth, at any tick length.
    #[test]
    fn conversion_variance_is_density_times_noise_bandwidth() {
        for period in [1.0 / 199.6e3, 1.0 / 20e3] {
            let n = SensorNoise::new(1e-6, 15e3, 0.0, period, 4, 1e6);
            let want = 1e-12 * PI / (2.0 * SQRT_2) * 15e3;
            assert!((n.conversion_variance() / want - 1.0).abs() < 1e-9);
        }
    }

    /// The innovations model keeps the exact model's variance: the averaged noise of four
    /// conversions 1 µs apart, against the covariance of the continuous process at those lags.
    #[test]
    fn sampled_variance_is_the_mean_of_the_conversions_covariance() {
        let (fc, period) = (15e3, 1.0 / 20e3);
        let noise = SensorNoise::new(1e-6, fc, 0.0, period, 4, 1e6);
        let s = noise.sampled(4);
        let k = &s.sys.b;
        let (p, _) = lti::dlyap(&s.sys.a, &(k * k.transpose() * s.variance)).unwrap();
        let model = (&s.sys.c * p * s.sys.c.transpose())[(0, 0)] + s.variance;
        // Autocovariance of the Butterworth-filtered white noise, r(τ) = r(0)·e^{−ζωτ}
        // (cos ω_d τ + ζ/√(1−ζ²) sin ω_d τ), ζ = 1/√2.
        let w = 2.0 * PI * fc;
        let (zeta, wd) = (1.0 / SQRT_2, w / SQRT_2);
        let r0 = noise.conversion_variance();
        let r = |tau: f64| {
            r0 * libm::exp(-zeta * w * tau) * (libm::cos(wd * tau) + libm::sin(wd * tau))
        };
        let mut want = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                want += r((i as f64 - j as f64).abs() * 1e-6) / 16.0;
            }
        }
        assert!((model / want - 1.0).abs() < 1e-6, "{model} vs {want}");
    }

    /// The lag covariance is the Butterworth's analytic autocovariance.
    #[test]
    fn lag_covariance_is_the_butterworths() {
        let fc = 15e3;
        let noise = SensorNoise::new(1e-6, fc, 0.0, 1.0 / 199.6e3, 4, 1e6);
        let w = 2.0 * PI * fc;
        let (zeta, wd) = (1.0 / SQRT_2, w / SQRT_2);
        let r0 = noise.conversion_variance();
        for tau in [0.0, 1e-6, 3e-6, 2e-5, 1e-4] {
            let want =
                r0 * libm::exp(-zeta * w * tau) * (libm::cos(wd * tau) + libm::sin(wd * tau));
            let got = noise.lag_covariance(tau);
            assert!((got - want).abs() < 1e-9 * r0, "τ {tau}: {got} vs {want}");
            assert_eq!(noise.lag_covariance(-tau), got);
        }
    }
}
