//! FIR feedforward from frequency-response data: the taps `h` of
//! `H(z) = Σᵢ hᵢ·z^{p−i·s}` (p ticks of preview, taps s ticks apart) that make a measured loop `T` (reference →
//! tool, m/m) flat, `T·H ≈ 1` in gain and phase over a band — a convex least-squares problem
//! (weighted by each bin's confidence, a small ridge on the taps), with the DC gain exact and
//! `|H|` bounded above the band so the filter never amplifies what it was not fitted on.
//! Solved by clarabel. Data-driven: it needs no model of `T`, only `T` at the bins
//! (as Wu et al., MSSP 2025, fitted FIR feedforward to a measured FRF).

use crate::lp::{solve_conic, Block};
use num_complex::Complex64;

/// What to fit.
#[derive(Debug, Clone, Copy)]
pub struct FirProblem<'a> {
    /// The bins' frequencies, Hz (those above `band_hz` are ignored).
    pub freq_hz: &'a [f64],
    /// The loop to flatten at each bin (m/m).
    pub path: &'a [Complex64],
    /// Each bin's weight (≥ 0; e.g. its coherence).
    pub weight: &'a [f64],
    /// The loop's gain at DC (m/m): `Σ h = 1 / dc_gain` exactly.
    pub dc_gain: f64,
    /// Servo period, s.
    pub period_s: f64,
    /// Number of taps.
    pub taps: usize,
    /// Ticks of preview (the first tap's lead).
    pub preview: usize,
    /// Ticks between taps (≥ 1; the band must lie below `1/(2·stride·period)`).
    pub stride: usize,
    /// Upper end of the fitted band, Hz.
    pub band_hz: f64,
    /// Largest |H| above the band (m/m).
    pub max_gain_above_band: f64,
}

/// The fitted filter.
#[derive(Debug, Clone, PartialEq)]
pub struct FirDesign {
    /// The taps (m/m), `taps[0]` multiplying the trajectory `preview` ticks ahead.
    pub taps: Vec<f64>,
    /// Ticks of preview.
    pub preview: usize,
    /// Ticks between taps.
    pub stride: usize,
    /// The fitted bins: indices into the problem's `freq_hz` (those at or below the band,
    /// with weight and a finite response).
    pub bins: Vec<usize>,
    /// `|T·H − 1|` at each fitted bin.
    pub residual: Vec<f64>,
    /// `|H|` at each fitted bin.
    pub gain: Vec<f64>,
}

/// Why no filter was fitted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum FirError {
    /// Fewer bins in the band than the fit needs.
    #[error("{bins} measured bins at or below {band_hz} Hz (at least {need} needed: measure more points in the band or widen it)")]
    TooFewBins {
        /// Bins in the band.
        bins: usize,
        /// The band, Hz.
        band_hz: f64,
        /// Bins needed.
        need: usize,
    },
    /// A value out of range.
    #[error("{what}")]
    Invalid {
        /// What is wrong.
        what: String,
    },
    /// clarabel did not solve the problem.
    #[error("the least-squares fit did not solve ({0})")]
    Solver(String),
}

/// Relative weight of the ridge on the taps (against the band's mean weight).
const RIDGE: f64 = 1e-10;
/// Frequencies above the band where |H| is bounded.
const BOUND_FREQUENCIES: usize = 96;
/// Fewest bins in the band.
const MIN_BINS: usize = 4;

/// `H(e^{jωT})` of `taps` `stride` ticks apart with `preview` ticks of lead, at `f_hz`.
pub fn response(
    taps: &[f64],
    preview: usize,
    stride: usize,
    f_hz: f64,
    period_s: f64,
) -> Complex64 {
    taps.iter()
        .enumerate()
        .map(|(i, &h)| h * tap_phasor(i * stride, preview, f_hz, period_s))
        .sum()
}

/// Fits the taps of `p`.
pub fn design(p: &FirProblem) -> Result<FirDesign, FirError> {
    let invalid = |what: String| Err(FirError::Invalid { what });
    if p.taps == 0 || p.preview >= p.taps.max(1) * 4 {
        return invalid(format!(
            "{} taps with {} ticks of preview: at least one tap, preview below four times the taps",
            p.taps, p.preview
        ));
    }
    if p.stride == 0 {
        return invalid("stride 0: taps are at least one tick apart".into());
    }
    // The filter's response repeats every rate/stride: it is bounded up to half of that.
    let nyquist = 0.5 / (p.period_s * p.stride as f64);
    if !(p.band_hz > 0.0 && p.band_hz < nyquist) {
        return invalid(format!(
            "band {} Hz: must lie in (0, {nyquist}) Hz, below half the rate over the stride",
            p.band_hz
        ));
    }
    if !(p.dc_gain.is_finite() && p.dc_gain.abs() > 1e-6) {
        return invalid(format!(
            "DC gain {}: must be finite and not zero",
            p.dc_gain
        ));
    }
    if p.max_gain_above_band.is_nan() || p.max_gain_above_band <= 0.0 {
        return invalid(format!(
            "gain bound {}: must be positive",
            p.max_gain_above_band
        ));
    }
    let bins: Vec<usize> = (0..p.freq_hz.len())
        .filter(|&k| {
            p.freq_hz[k] <= p.band_hz
                && p.weight[k] > 0.0
                && p.path[k].re.is_finite()
                && p.path[k].im.is_finite()
        })
        .collect();
    if bins.len() < MIN_BINS {
        return Err(FirError::TooFewBins {
            bins: bins.len(),
            band_hz: p.band_hz,
            need: MIN_BINS,
        });
    }
    let n = p.taps;
    let total: f64 = bins.iter().map(|&k| p.weight[k]).sum();
    // x = [h, t]: min t with ‖[√w·(a·h − 1) (re, im); √ridge·h]‖ ≤ t, a_i = T·e^{jω(p−i)T}
    // (clarabel's form: b − A·x in the cone).
    let (mut rows, mut b) = (Vec::new(), Vec::new());
    let row = |coeffs: &dyn Fn(usize) -> f64, last: f64| -> Vec<f64> {
        (0..n).map(coeffs).chain(std::iter::once(last)).collect()
    };
    // Σ h = 1/dc.
    rows.push(row(&|_| 1.0, 0.0));
    b.push(1.0 / p.dc_gain);
    // The fit's cone.
    rows.push(row(&|_| 0.0, -1.0));
    b.push(0.0);
    for &k in &bins {
        let w = (p.weight[k] / total).sqrt();
        let a: Vec<Complex64> = (0..n)
            .map(|i| p.path[k] * tap_phasor(i * p.stride, p.preview, p.freq_hz[k], p.period_s))
            .collect();
        rows.push(row(&|i| -w * a[i].re, 0.0));
        b.push(-w);
        rows.push(row(&|i| -w * a[i].im, 0.0));
        b.push(0.0);
    }
    for i in 0..n {
        rows.push(row(&|j| if i == j { -RIDGE.sqrt() } else { 0.0 }, 0.0));
        b.push(0.0);
    }
    let mut blocks = vec![Block::Equal(1), Block::Cone(1 + 2 * bins.len() + n)];
    // |H(f)| ≤ bound above the band: (bound, Re H, Im H) in a cone at each frequency.
    for m in 0..BOUND_FREQUENCIES {
        let f = p.band_hz + (nyquist - p.band_hz) * (m as f64 + 0.5) / BOUND_FREQUENCIES as f64;
        rows.push(row(&|_| 0.0, 0.0));
        b.push(p.max_gain_above_band);
        let phasor = |i: usize| tap_phasor(i * p.stride, p.preview, f, p.period_s);
        rows.push(row(&|i| -phasor(i).re, 0.0));
        b.push(0.0);
        rows.push(row(&|i| -phasor(i).im, 0.0));
        b.push(0.0);
        blocks.push(Block::Cone(3));
    }
    let mut q = vec![0.0; n + 1];
    q[n] = 1.0;
    let mut taps = solve_conic(&q, &rows, &b, &blocks).map_err(FirError::Solver)?;
    taps.truncate(n);
    let h: Vec<Complex64> = bins
        .iter()
        .map(|&k| response(&taps, p.preview, p.stride, p.freq_hz[k], p.period_s))
        .collect();
    Ok(FirDesign {
        residual: bins
            .iter()
            .zip(&h)
            .map(|(&k, h)| (p.path[k] * h - 1.0).norm())
            .collect(),
        gain: h.iter().map(|h| h.norm()).collect(),
        bins,
        taps,
        preview: p.preview,
        stride: p.stride,
    })
}

/// The factor in `H` at `f_hz` of a tap `delay` ticks after the first: `e^{jω(preview − delay)T}`.
fn tap_phasor(delay: usize, preview: usize, f_hz: f64, period_s: f64) -> Complex64 {
    let w = 2.0 * std::f64::consts::PI * f_hz * period_s;
    Complex64::from_polar(1.0, w * (preview as f64 - delay as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fit of `path` at `freq` (equal weights, DC gain 1, taps one tick apart, 0.1 ms).
    fn fit(
        freq: &[f64],
        path: &[Complex64],
        (taps, preview): (usize, usize),
        band_hz: f64,
        max_gain_above_band: f64,
    ) -> FirDesign {
        design(&FirProblem {
            freq_hz: freq,
            path,
            weight: &vec![1.0; freq.len()],
            dc_gain: 1.0,
            period_s: 1e-4,
            taps,
            preview,
            stride: 1,
            band_hz,
            max_gain_above_band,
        })
        .unwrap()
    }

    /// A pure delay of `d` ticks is inverted exactly by a preview of `d` ticks: fitted up to
    /// near Nyquist, the fit finds the single tap.
    #[test]
    fn a_delay_is_inverted_by_preview() {
        let period = 1e-4;
        let freq: Vec<f64> = (1..160).map(|k| 25.0 * k as f64).collect();
        let path: Vec<Complex64> = freq
            .iter()
            .map(|f| Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * period * 3.0))
            .collect();
        let d = fit(&freq, &path, (12, 5), 3975.0, 1.5);
        for (i, t) in d.taps.iter().enumerate() {
            let want = if i == 2 { 1.0 } else { 0.0 };
            assert!((t - want).abs() < 1e-5, "tap {i}: {t}");
        }
        assert!(d.residual.iter().all(|r| *r < 1e-5));
    }

    /// A first-order lag `a/(1 − (1−a) z⁻¹)` is inverted by two taps `(1 − (1−a) z⁻¹)/a`,
    /// the second and third with one tick of preview; fitted up to near Nyquist (where the
    /// taps are determined), the fit finds them.
    #[test]
    fn a_first_order_lag_is_flattened() {
        let (period, a) = (1e-4, 0.3);
        let freq: Vec<f64> = (1..200).map(|k| 20.0 * k as f64).collect();
        let path: Vec<Complex64> = freq
            .iter()
            .map(|f| {
                let z1 = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * f * period);
                a / (1.0 - (1.0 - a) * z1)
            })
            .collect();
        let d = fit(&freq, &path, (6, 1), 3980.0, 10.0);
        let want = [0.0, 1.0 / a, -(1.0 - a) / a, 0.0, 0.0, 0.0];
        for (t, w) in d.taps.iter().zip(want) {
            assert!((t - w).abs() < 1e-4, "{:?}", d.taps);
        }
    }

    /// The bound holds above the band even when the data ask for more: a loop that falls
    /// steeply would need a large gain to flatten near the band's edge.
    #[test]
    fn the_gain_above_the_band_stays_bounded() {
        let period = 1e-4;
        let freq: Vec<f64> = (1..40).map(|k| 25.0 * k as f64).collect();
        let path: Vec<Complex64> = freq
            .iter()
            .map(|f| Complex64::new(1.0, 0.0) / (1.0 + Complex64::new(0.0, f / 200.0)).powi(2))
            .collect();
        let bound = 2.0;
        let d = fit(&freq, &path, (24, 12), 1000.0, bound);
        let sum: f64 = d.taps.iter().sum();
        assert!((sum - 1.0).abs() < 1e-7, "DC gain {sum}");
        for k in 0..400 {
            let f = 1050.0 + (5000.0 - 1050.0) * k as f64 / 400.0;
            let h = response(&d.taps, d.preview, 1, f, period).norm();
            assert!(h <= bound * 1.01, "{f} Hz: |H| = {h}");
        }
    }
}
