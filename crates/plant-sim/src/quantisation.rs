//! The ADC's rounding error on the tick-averaged gap reading, as a stationary process.
//!
//! Each conversion rounds the gap voltage (position plus sensor noise) to the nearest code;
//! the tick's reading averages `oversampling` conversions 1/f_adc apart (thesis §4.5.2). The
//! rounding error of one conversion is uniform over an LSB Δ (variance Δ²/12) when the
//! noise spreads the voltage over more than about a third of an LSB (the default sensor noise
//! is ≈ 1 LSB RMS). But the errors of conversions close in time are not independent: the
//! band-limited noise moves far less than an LSB in 1 µs, so the four conversions of a tick
//! round nearly the same voltage and the average keeps much of their error — about 2.3× the
//! `Δ²/(12·oversampling)` an independent model gives, at the thesis defaults.
//!
//! For two conversions whose voltages differ by a Gaussian `d` of variance `D(τ)` (τ apart),
//! the rounding errors' covariance is the sawtooth's circular autocorrelation averaged over
//! `d`:
//!
//! ```text
//! R(τ) = E[Δ²/12 − d̃(Δ − d̃)/2],  d̃ = d mod Δ
//!      = Δ²/(2π²) Σ_{k≥1} exp(−2π²k² D(τ)/Δ²) / k²          (the Gaussian-difference series)
//! ```
//!
//! with `D(τ) = 2(C(0) − C(τ))` from the sensor noise's lag covariance `C`
//! ([`crate::sensor_noise::SensorNoise::lag_covariance`]). Averaging over the conversion grid
//! gives the tick-averaged error's autocovariance at every lag, and that, realised exactly
//! ([`SampledNoise::from_autocovariance`]), is what the closed loop, the budget and the H2
//! design take.
//!
//! What it assumes, and when that fails: the stage holds position. The stage's own motion
//! while it holds (sub-nanometre, within the servo bandwidth) changes `D` by parts in 10⁴
//! over the few microseconds that matter and is left out; a moving reference (a 5 µm sine at
//! 200 Hz moves ≈ 8 LSB per µs) decorrelates the conversions and the term falls towards
//! `Δ²/(12·oversampling)`. Without sensor noise nothing dithers the converter and the error is
//! a fixed offset, not a random process: the independent model is kept there, as a bound.

use crate::sampled_noise::{SampledNoise, MAX_LAGS};
use crate::sensor_noise::SensorNoise;
use std::f64::consts::PI;

/// Covariance of the rounding errors (quantiser step `lsb`, V) of two conversions whose
/// voltages differ by a zero-mean Gaussian of variance `difference_variance` (V²), V².
pub fn rounding_covariance(lsb: f64, difference_variance: f64) -> f64 {
    let d = difference_variance.max(0.0);
    let a = 2.0 * PI * PI * d / (lsb * lsb);
    if a < 0.2 {
        // Small differences: |d| exceeds Δ with probability below erfc(7) ≈ 10⁻²³, so no
        // wrap, and E[d̃(Δ − d̃)] = Δ·E|d| − E[d²].
        return lsb * lsb / 12.0 - lsb * (2.0 * d / PI).sqrt() / 2.0 + d / 2.0;
    }
    // Terms fall as e^{−a k²}: stop once below 10⁻¹⁸ of the first.
    let mut sum = 0.0;
    let mut k = 1.0_f64;
    loop {
        let term = libm::exp(-a * k * k) / (k * k);
        sum += term;
        if a * k * k > 41.0 {
            break;
        }
        k += 1.0;
    }
    lsb * lsb / (2.0 * PI * PI) * sum
}

/// The conversions of a tick: `oversampling` of them `1/conversion_rate_hz` apart, the last on
/// the tick, ticks `period_s` apart.
#[derive(Debug, Clone, Copy)]
pub struct ConversionGrid {
    /// Servo period, s.
    pub period_s: f64,
    /// Conversions averaged per tick.
    pub oversampling: u32,
    /// Conversion rate, Hz.
    pub conversion_rate_hz: f64,
}

impl ConversionGrid {
    /// Autocovariance at lags 0, 1, … ticks of the mean of each tick's values of a process
    /// whose values at two conversions τ apart have covariance `covariance(τ)`; it stops at
    /// the last lag above `1e-12` of lag 0 (at most [`MAX_LAGS`]).
    fn averaged_autocovariance(&self, covariance: impl Fn(f64) -> f64) -> Vec<f64> {
        let os = self.oversampling.max(1) as usize;
        let spacing = 1.0 / self.conversion_rate_hz;
        let at_lag = |m: usize| {
            let mut sum = 0.0;
            for c in 0..os {
                for c2 in 0..os {
                    let tau = m as f64 * self.period_s + (c2 as f64 - c as f64) * spacing;
                    sum += covariance(tau.abs());
                }
            }
            sum / (os * os) as f64
        };
        let mut r = vec![at_lag(0)];
        for m in 1..=MAX_LAGS {
            let x = at_lag(m);
            if x.abs() <= 1e-12 * r[0] {
                break;
            }
            r.push(x);
        }
        r
    }
}

/// The rounding error of the tick-averaged reading of an ADC of step `lsb` (V) converting
/// the gap voltage with `noise` on it, on `grid`, as a per-tick process (V): coloured by
/// the noise's correlation, or, without noise (nothing dithers the converter), white with
/// the independent-conversion variance `lsb²/(12·oversampling)`. None for an ideal converter.
pub fn averaged_rounding_error(
    lsb: f64,
    noise: Option<&SensorNoise>,
    grid: &ConversionGrid,
) -> Option<SampledNoise> {
    if lsb.is_nan() || lsb <= 0.0 {
        return None;
    }
    let independent = lsb * lsb / 12.0 / grid.oversampling.max(1) as f64;
    let Some(noise) = noise else {
        return Some(SampledNoise::white(independent));
    };
    let c0 = noise.conversion_variance();
    let r = grid.averaged_autocovariance(|tau| {
        rounding_covariance(lsb, 2.0 * (c0 - noise.lag_covariance(tau)))
    });
    // An autocovariance of a real process always has a realisation; the white fallback
    // keeps the exact variance should rounding defeat the factorisation.
    Some(SampledNoise::from_autocovariance(&r).unwrap_or_else(|| SampledNoise::white(r[0])))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The two forms of R agree where both hold, R(0) = Δ²/12, and far apart the errors are
    /// independent.
    #[test]
    fn rounding_covariance_forms_agree() {
        let lsb = 1.0;
        assert!((rounding_covariance(lsb, 0.0) - 1.0 / 12.0).abs() < 1e-15);
        // At a = 0.2 both are exact: compare the series (forced) with the direct form.
        let d = 0.2 / (2.0 * PI * PI);
        let series: f64 = (1..200)
            .map(|k| {
                let k = k as f64;
                libm::exp(-0.2 * k * k) / (k * k)
            })
            .sum::<f64>()
            / (2.0 * PI * PI);
        let direct = 1.0 / 12.0 - (2.0 * d / PI).sqrt() / 2.0 + d / 2.0;
        assert!((series - direct).abs() < 1e-12, "{series} vs {direct}");
        assert!((rounding_covariance(lsb, d * 1.0001) - direct).abs() < 1e-5);
        assert!(rounding_covariance(lsb, 4.0).abs() < 1e-30);
    }
}
