//! Spectral estimation: Welch power spectral density and the DFT at an exact bin (thesis
//! eq 5-11), on realfft.

use num_complex::Complex64;
use realfft::RealFftPlanner;

/// Spectral estimation errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SpectralError {
    /// The record is shorter than one segment.
    #[error("record of {len} samples is shorter than one segment of {segment_len}")]
    TooShort {
        /// Record length.
        len: usize,
        /// Segment length.
        segment_len: usize,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Argument(&'static str),
}

/// Data window applied to each Welch segment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Window {
    /// No window (boxcar).
    Rectangular,
    /// Periodic Hann window.
    Hann,
}

impl Window {
    pub(crate) fn coefficients(self, n: usize) -> Vec<f64> {
        match self {
            Window::Rectangular => vec![1.0; n],
            Window::Hann => (0..n)
                .map(|i| 0.5 - 0.5 * libm::cos(2.0 * std::f64::consts::PI * i as f64 / n as f64))
                .collect(),
        }
    }
}

/// Welch settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WelchConfig {
    /// Samples per segment (frequency resolution `fs / segment_len`).
    pub segment_len: usize,
    /// Fraction of a segment shared with the next, in [0, 1).
    pub overlap: f64,
    /// Window applied to each segment (the segment mean is removed first).
    pub window: Window,
}

impl WelchConfig {
    /// Hann window, 50 % overlap.
    pub fn hann(segment_len: usize) -> Self {
        WelchConfig {
            segment_len,
            overlap: 0.5,
            window: Window::Hann,
        }
    }
}

/// A one-sided power spectral density: `density[i]` in unit²/Hz at `freq_hz[i]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Psd {
    /// Bin frequencies in Hz, from 0 to Nyquist.
    pub freq_hz: Vec<f64>,
    /// One-sided density in unit²/Hz.
    pub density: Vec<f64>,
}

impl Psd {
    /// Bin spacing in Hz.
    pub fn bin_hz(&self) -> f64 {
        self.freq_hz.get(1).copied().unwrap_or(0.0)
    }

    /// Mean-square content between `f_lo_hz` and `f_hi_hz` (inclusive bins), unit².
    pub fn band_power(&self, f_lo_hz: f64, f_hi_hz: f64) -> f64 {
        self.freq_hz
            .iter()
            .zip(&self.density)
            .filter(|(f, _)| **f >= f_lo_hz && **f <= f_hi_hz)
            .map(|(_, d)| d * self.bin_hz())
            .sum()
    }
}

/// `n` log-spaced frequencies from `from_hz` to `to_hz` inclusive (`n ≥ 2`; one point at
/// `from_hz` if `n < 2`).
///
/// ```
/// let f = lti::spectral::log_space(10.0, 1000.0, 3);
/// assert_eq!(f, vec![10.0, 100.0, 1000.0]);
/// ```
pub fn log_space(from_hz: f64, to_hz: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| from_hz * libm::pow(to_hz / from_hz, i as f64 / (n - 1).max(1) as f64))
        .collect()
}

/// Cumulative amplitude spectrum (thesis eq 5-16): `CAS(f_i) = √(Σ_{k≤i} PSD_k·Δf_k)`, the RMS
/// content from DC up to each frequency (trapezoidal weights on a possibly uneven grid, the
/// first point weighted by its half interval). By Parseval (eq 5-17) `CAS(f_max)` is the RMS.
pub fn cas(freq_hz: &[f64], psd: &[f64]) -> Vec<f64> {
    let mut acc = 0.0;
    let mut out = Vec::with_capacity(psd.len());
    for i in 0..psd.len() {
        if i > 0 {
            acc += 0.5 * (psd[i] + psd[i - 1]) * (freq_hz[i] - freq_hz[i - 1]);
        }
        out.push(acc.sqrt());
    }
    out
}

impl Psd {
    /// The cumulative amplitude spectrum of this estimate, summing whole bins (rectangle rule,
    /// so that the value at Nyquist is exactly the band power of all bins).
    pub fn cas(&self) -> Vec<f64> {
        cas_of_bins(&self.density, self.bin_hz())
    }
}

/// The cumulative amplitude spectrum of a PSD on uniform bins `bin_hz` apart, summing whole
/// bins (rectangle rule): the last value is the RMS of all the bins.
pub fn cas_of_bins(density: &[f64], bin_hz: f64) -> Vec<f64> {
    let mut acc = 0.0;
    density
        .iter()
        .map(|d| {
            acc += d * bin_hz;
            acc.sqrt()
        })
        .collect()
}

/// Welch's averaged periodogram of `x` sampled at `fs_hz`.
pub fn welch(x: &[f64], fs_hz: f64, cfg: &WelchConfig) -> Result<Psd, SpectralError> {
    let mut w = Welch::new(fs_hz, cfg)?;
    for &v in x {
        w.push(v);
    }
    w.finish()
}

/// Welch's averaged periodogram computed as samples arrive, in constant memory (one segment):
/// a recording of any length streams through it. Segments start every
/// `segment_len·(1 − overlap)` samples, as [`welch`] takes them.
pub struct Welch {
    fs_hz: f64,
    step: usize,
    window: Vec<f64>,
    fft: std::sync::Arc<dyn realfft::RealToComplex<f64>>,
    /// The last `segment_len` samples, oldest at `head` once full.
    ring: Vec<f64>,
    head: usize,
    seen: usize,
    input: Vec<f64>,
    spectrum: Vec<Complex64>,
    acc: Vec<f64>,
    segments: usize,
}

impl Welch {
    /// An empty estimate of a signal sampled at `fs_hz` with the settings `cfg`.
    pub fn new(fs_hz: f64, cfg: &WelchConfig) -> Result<Self, SpectralError> {
        let n = cfg.segment_len;
        if n < 2 {
            return Err(SpectralError::Argument("segment_len must be at least 2"));
        }
        if !(0.0..1.0).contains(&cfg.overlap) {
            return Err(SpectralError::Argument("overlap must lie in [0, 1)"));
        }
        if !(fs_hz.is_finite() && fs_hz > 0.0) {
            return Err(SpectralError::Argument("the sample rate must be positive"));
        }
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        Ok(Welch {
            fs_hz,
            step: ((n as f64 * (1.0 - cfg.overlap)).round() as usize).max(1),
            window: cfg.window.coefficients(n),
            input: fft.make_input_vec(),
            spectrum: fft.make_output_vec(),
            fft,
            ring: vec![0.0; n],
            head: 0,
            seen: 0,
            acc: vec![0.0; n / 2 + 1],
            segments: 0,
        })
    }

    /// Takes the next sample.
    pub fn push(&mut self, v: f64) {
        let n = self.ring.len();
        self.ring[self.head] = v;
        self.head = (self.head + 1) % n;
        self.seen += 1;
        if self.seen >= n && (self.seen - n).is_multiple_of(self.step) {
            self.add_segment();
        }
    }

    /// Segments averaged so far.
    pub fn segments(&self) -> usize {
        self.segments
    }

    /// The periodogram of the last `segment_len` samples, mean removed and windowed, added.
    fn add_segment(&mut self) {
        let n = self.ring.len();
        let (newer, older) = self.ring.split_at(self.head);
        let mean = self.ring.iter().sum::<f64>() / n as f64;
        for ((dst, &v), &w) in self
            .input
            .iter_mut()
            .zip(older.iter().chain(newer))
            .zip(&self.window)
        {
            *dst = (v - mean) * w;
        }
        // The lengths are the plan's own: processing cannot fail.
        if self
            .fft
            .process(&mut self.input, &mut self.spectrum)
            .is_ok()
        {
            for (a, c) in self.acc.iter_mut().zip(&self.spectrum) {
                *a += c.norm_sqr();
            }
            self.segments += 1;
        }
    }

    /// The estimate: one-sided density in unit²/Hz from DC to Nyquist.
    pub fn finish(&self) -> Result<Psd, SpectralError> {
        let n = self.ring.len();
        if self.segments == 0 {
            return Err(SpectralError::TooShort {
                len: self.seen,
                segment_len: n,
            });
        }
        let window_power: f64 = self.window.iter().map(|w| w * w).sum();
        let scale = 1.0 / (self.fs_hz * window_power * self.segments as f64);
        let nyquist_bin = n.is_multiple_of(2).then_some(n / 2);
        let density = self
            .acc
            .iter()
            .enumerate()
            .map(|(i, a)| {
                let one_sided = if i == 0 || Some(i) == nyquist_bin {
                    1.0
                } else {
                    2.0
                };
                a * scale * one_sided
            })
            .collect();
        let freq_hz = (0..=n / 2)
            .map(|i| i as f64 * self.fs_hz / n as f64)
            .collect();
        Ok(Psd { freq_hz, density })
    }
}

/// H1 frequency-response estimate at one exact bin from `blocks` equal blocks of the
/// excitation `u` and response `y` (each block an integer `cycles` of the excitation):
/// `H1 = Σ Y·U* / Σ |U|²` and the magnitude-squared coherence
/// `γ² = |Σ Y·U*|² / (Σ|U|²·Σ|Y|²)` (1 when the response is linear and noise-free).
pub fn h1_at_bin(u: &[f64], y: &[f64], cycles: usize, blocks: usize) -> (Complex64, f64) {
    let n = u.len().min(y.len()) / blocks.max(1);
    let (mut yu, mut uu, mut yy) = (Complex64::new(0.0, 0.0), 0.0, 0.0);
    for b in 0..blocks.max(1) {
        let (ub, yb) = (
            dft_bin(&u[b * n..(b + 1) * n], cycles),
            dft_bin(&y[b * n..(b + 1) * n], cycles),
        );
        yu += yb * ub.conj();
        uu += ub.norm_sqr();
        yy += yb.norm_sqr();
    }
    (yu / uu, yu.norm_sqr() / (uu * yy))
}

/// The uncertainty of an H1 estimate `h` with coherence `coherence` averaged over `blocks`
/// repeats of the same excitation (a stepped sine's blocks, a periodic chirp's sweeps): the
/// radius of the disk around `h` that holds the true response with the probability a complex
/// Gaussian error's 1σ disk has (1 − e⁻¹ ≈ 63 %), in the unit of `h`.
///
/// With the excitation identical in every block, `|h|²·(1 − γ²)/γ²/(n − 1)` is the spread of
/// the blocks' estimates about their mean divided by `n` (the mean's variance, the blocks'
/// noise independent); that variance estimated from `n` blocks makes `|ĥ − h|²/σ̂²` an
/// F(2, 2n − 2) variable, whose 63 % point is `(n − 1)(e^{1/(n−1)} − 1)`. Infinite for fewer
/// than two blocks or a coherence of zero; zero at a coherence of one (no noise).
pub fn h1_uncertainty(h: Complex64, coherence: f64, blocks: usize) -> f64 {
    if blocks < 2 || coherence <= 0.0 {
        return f64::INFINITY;
    }
    let spread = (1.0 - coherence).max(0.0) / coherence;
    let m = (blocks - 1) as f64;
    h.norm() * libm::sqrt(spread * (libm::exp(1.0 / m) - 1.0))
}

/// The uncertainty of a frequency response measured with a periodic excitation at one exact
/// bin (`cycles` periods of a sine in the whole record, as [`dft_bin`]): the noise the response
/// carries at the bin, estimated from the `neighbours` bins on each side of it in the whole
/// record (which a periodic excitation leaves empty), over the excitation's amplitude there. In
/// the unit of `y / u`; the radius that holds the truth with a complex Gaussian 1σ disk's
/// probability (1 − e⁻¹ ≈ 63 %), corrected for the bins it was estimated from (an
/// F(2, 4·neighbours) ratio). Unlike the spread of block estimates, it is not inflated by
/// drift the blocks see and their mean does not (leakage falls as 1/cycles).
pub fn periodic_uncertainty(u: &[f64], y: &[f64], cycles: usize, neighbours: usize) -> f64 {
    let n = u.len().min(y.len());
    let excitation = dft_bin(&u[..n], cycles).norm_sqr();
    let (mut power, mut bins) = (0.0, 0usize);
    for j in 1..=neighbours {
        for c in [cycles.checked_sub(j), Some(cycles + j)]
            .into_iter()
            .flatten()
        {
            if c > 0 && 2 * c < n {
                power += dft_bin(&y[..n], c).norm_sqr();
                bins += 1;
            }
        }
    }
    if bins == 0 || excitation <= 0.0 {
        return f64::INFINITY;
    }
    let m = bins as f64;
    libm::sqrt(power / m / excitation * m * (libm::exp(1.0 / m) - 1.0))
}

/// A frequency response estimated from broadband data (chirp, burst random).
#[derive(Debug, Clone, PartialEq)]
pub struct Frf {
    /// Bin frequencies in Hz.
    pub freq_hz: Vec<f64>,
    /// H1 estimate `S_yu / S_uu` per bin (output unit per input unit).
    pub h: Vec<Complex64>,
    /// Magnitude-squared coherence per bin.
    pub coherence: Vec<f64>,
}

/// Welch-averaged H1 estimate and coherence from excitation `u` and response `y`.
pub fn h1_welch(u: &[f64], y: &[f64], fs_hz: f64, cfg: &WelchConfig) -> Result<Frf, SpectralError> {
    let n = cfg.segment_len;
    let len = u.len().min(y.len());
    if len < n || n < 2 {
        return Err(SpectralError::TooShort {
            len,
            segment_len: n,
        });
    }
    let step = ((n as f64 * (1.0 - cfg.overlap)).round() as usize).max(1);
    let window = cfg.window.coefficients(n);
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let (mut bu, mut by) = (fft.make_input_vec(), fft.make_input_vec());
    let (mut su, mut sy) = (fft.make_output_vec(), fft.make_output_vec());
    let bins = n / 2 + 1;
    let (mut suu, mut syy, mut syu) = (
        vec![0.0; bins],
        vec![0.0; bins],
        vec![Complex64::new(0.0, 0.0); bins],
    );
    for start in (0..=len - n).step_by(step) {
        for i in 0..n {
            bu[i] = u[start + i] * window[i];
            by[i] = y[start + i] * window[i];
        }
        fft.process(&mut bu, &mut su)
            .map_err(|_| SpectralError::Argument("FFT length mismatch"))?;
        fft.process(&mut by, &mut sy)
            .map_err(|_| SpectralError::Argument("FFT length mismatch"))?;
        for k in 0..bins {
            suu[k] += su[k].norm_sqr();
            syy[k] += sy[k].norm_sqr();
            syu[k] += sy[k] * su[k].conj();
        }
    }
    Ok(Frf {
        freq_hz: (0..bins).map(|k| k as f64 * fs_hz / n as f64).collect(),
        h: (0..bins).map(|k| syu[k] / suu[k]).collect(),
        coherence: (0..bins)
            .map(|k| syu[k].norm_sqr() / (suu[k] * syy[k]))
            .collect(),
    })
}

/// Complex amplitude `A·e^{jφ}` of the component `A·cos(2π·cycles·n/N + φ)` of a record of `N`
/// samples holding an integer number of periods (thesis eq 5-11: no leakage at an exact bin).
///
/// The twiddle `e^{−j2π·cycles·k/N}` is rotated from sample to sample and set exactly (its
/// phase reduced modulo 2π in integers) every 256 samples, so the rounding stays at
/// `256·ε` for any record length at one complex product per sample: a
/// stepped sine's low-frequency point (10⁶ samples, a dozen bins) is estimated in
/// milliseconds while the plant waits.
pub fn dft_bin(x: &[f64], cycles: usize) -> Complex64 {
    let n = x.len();
    if n == 0 {
        return Complex64::new(0.0, 0.0);
    }
    let turn = |k: usize| {
        // k·cycles mod N in integers: the phase of sample k without a large angle's rounding.
        let r = (k as u128 * cycles as u128 % n as u128) as f64;
        Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * r / n as f64)
    };
    let step = turn(1);
    let mut sum = Complex64::new(0.0, 0.0);
    for (c, chunk) in x.chunks(TWIDDLE_ANCHOR).enumerate() {
        let mut twiddle = turn(c * TWIDDLE_ANCHOR);
        for &v in chunk {
            sum += v * twiddle;
            twiddle *= step;
        }
    }
    sum * (2.0 / n as f64)
}

/// Samples between exact twiddles in [`dft_bin`].
const TWIDDLE_ANCHOR: usize = 256;

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};
    use rand_xoshiro::Xoshiro256PlusPlus;

    /// White noise of variance σ² sampled at fs has one-sided PSD 2σ²/fs. With K averaged Hann
    /// segments each bin scatters by ~1/√K; the band mean over many bins is within 2 %.
    #[test]
    fn welch_of_white_noise_has_known_level() {
        let (fs, sigma) = (199_600.0, 3e-3);
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let x: Vec<f64> = (0..1 << 20)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                sigma * z
            })
            .collect();
        let psd = welch(&x, fs, &WelchConfig::hann(4096)).unwrap();
        let expected = 2.0 * sigma * sigma / fs;
        let inner = &psd.density[10..psd.density.len() - 10];
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        assert!((mean / expected - 1.0).abs() < 0.02, "{mean} vs {expected}");
        // Total power over the band is the variance (Parseval through the window scaling).
        let total = psd.band_power(0.0, fs / 2.0);
        assert!((total / (sigma * sigma) - 1.0).abs() < 0.02);
    }

    /// Streaming Welch with 50 % overlap equals the mean of the single-segment estimates of
    /// the same slices (the segments are taken whole and in order), to rounding.
    #[test]
    fn overlapping_segments_are_the_mean_of_single_segment_estimates() {
        // Off-bin tone plus a ramp: any mis-ordered segment would leak differently.
        let (n, fs) = (256, 1000.0);
        let x: Vec<f64> = (0..1000)
            .map(|i| {
                libm::sin(2.0 * std::f64::consts::PI * 10.5 * i as f64 / n as f64) + 1e-3 * i as f64
            })
            .collect();
        let cfg = WelchConfig::hann(n);
        let all = welch(&x, fs, &cfg).unwrap();
        let peak = all.density.iter().cloned().fold(0.0, f64::max);
        let starts: Vec<usize> = (0..=x.len() - n).step_by(n / 2).collect();
        assert_eq!(starts.len(), 6);
        for (i, d) in all.density.iter().enumerate() {
            let mean = starts
                .iter()
                .map(|&s| welch(&x[s..s + n], fs, &cfg).unwrap().density[i])
                .sum::<f64>()
                / starts.len() as f64;
            assert!((d - mean).abs() <= 1e-12 * peak, "bin {i}: {d} vs {mean}");
        }
    }

    /// One rectangular segment without overlap: Σ PSD·Δf equals the mean-removed mean square
    /// exactly (Parseval), to 1e-12.
    #[test]
    fn single_rectangular_segment_is_parseval_exact() {
        let x: Vec<f64> = (0..1000)
            .map(|k| libm::sin((k * k) as f64 * 0.37) + 0.2)
            .collect();
        let cfg = WelchConfig {
            segment_len: 1000,
            overlap: 0.0,
            window: Window::Rectangular,
        };
        let psd = welch(&x, 1000.0, &cfg).unwrap();
        let mean = x.iter().sum::<f64>() / 1000.0;
        let ms = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / 1000.0;
        assert!((psd.band_power(0.0, 500.0) - ms).abs() < 1e-12 * ms);
    }

    /// CAS at Nyquist equals the time-domain RMS (Parseval, eq 5-17) to 1e-9 for one
    /// rectangular segment (mean removed).
    #[test]
    fn cas_at_nyquist_is_the_rms() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let x: Vec<f64> = (0..8192)
            .map(|k| {
                let z: f64 = StandardNormal.sample(&mut rng);
                1e-9 * z + 1e-10 * libm::sin(k as f64 * 0.01)
            })
            .collect();
        let cfg = WelchConfig {
            segment_len: x.len(),
            overlap: 0.0,
            window: Window::Rectangular,
        };
        let psd = welch(&x, 199_600.0, &cfg).unwrap();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        let rms = (x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt();
        let c = psd.cas();
        assert!((c.last().unwrap() - rms).abs() < 1e-9 * rms);
        assert!(c.windows(2).all(|w| w[1] >= w[0]));
        // The trapezoid form on the same grid agrees to the edge half-bins.
        let t = cas(&psd.freq_hz, &psd.density);
        assert!((t.last().unwrap() / rms - 1.0).abs() < 0.01);
    }

    /// A known FIR system y[k] = 0.5 u[k] + 0.25 u[k−1] driven by white noise: H1 equals
    /// 0.5 + 0.25 e^{−jω} and the coherence is 1; with output noise coherence drops.
    #[test]
    fn h1_and_coherence_of_a_known_system() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(11);
        let u: Vec<f64> = (0..1 << 16)
            .map(|_| StandardNormal.sample(&mut rng))
            .collect();
        let y: Vec<f64> = (0..u.len())
            .map(|k| 0.5 * u[k] + if k > 0 { 0.25 * u[k - 1] } else { 0.0 })
            .collect();
        let frf = h1_welch(&u, &y, 1000.0, &WelchConfig::hann(1024)).unwrap();
        for k in (1..512).step_by(37) {
            let w = 2.0 * std::f64::consts::PI * frf.freq_hz[k] / 1000.0;
            let want = Complex64::new(0.5, 0.0) + 0.25 * Complex64::from_polar(1.0, -w);
            assert!((frf.h[k] - want).norm() < 2e-3, "bin {k}");
            assert!(frf.coherence[k] > 0.999);
        }
        let noisy: Vec<f64> = y
            .iter()
            .map(|v| {
                let z: f64 = StandardNormal.sample(&mut rng);
                v + 0.5 * z
            })
            .collect();
        let frf = h1_welch(&u, &noisy, 1000.0, &WelchConfig::hann(1024)).unwrap();
        assert!(frf.coherence[100] < 0.9);
        // The stepped-sine form at an exact bin: a pure sine through the same system.
        let (n, c) = (4096, 64);
        let w = 2.0 * std::f64::consts::PI * c as f64 / n as f64;
        let us: Vec<f64> = (0..4 * n).map(|k| libm::sin(w * k as f64)).collect();
        let ys: Vec<f64> = (0..us.len())
            .map(|k| {
                0.5 * us[k]
                    + if k > 0 {
                        0.25 * us[k - 1]
                    } else {
                        0.25 * libm::sin(-w)
                    }
            })
            .collect();
        let (h, g) = h1_at_bin(&us, &ys, c, 4);
        let want = Complex64::new(0.5, 0.0) + 0.25 * Complex64::from_polar(1.0, -w);
        assert!((h - want).norm() < 1e-12 && (g - 1.0).abs() < 1e-12);
    }

    /// The stated radius is the blocks' standard error with the small-sample factor: over many
    /// noisy repeats of a known system, the truth lies inside it about 63 % of the time.
    #[test]
    fn h1_uncertainty_covers_the_truth_at_its_stated_rate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let (cycles, blocks, per) = (5usize, 8usize, 200usize);
        let truth = Complex64::from_polar(2.0e-6, -0.7);
        let w = 2.0 * std::f64::consts::PI * cycles as f64 / per as f64;
        let u: Vec<f64> = (0..per * blocks).map(|k| libm::cos(w * k as f64)).collect();
        let trials = 4000;
        let mut inside = 0;
        for _ in 0..trials {
            let y: Vec<f64> = (0..per * blocks)
                .map(|k| {
                    let clean = truth.norm() * libm::cos(w * k as f64 + truth.arg());
                    // Uniform noise of the same scale: not Gaussian, as a quantiser's is not.
                    clean + 4.0e-6 * (rng.random::<f64>() - 0.5)
                })
                .collect();
            let (h, g) = h1_at_bin(&u, &y, cycles, blocks);
            if (h - truth).norm() <= h1_uncertainty(h, g, blocks) {
                inside += 1;
            }
        }
        let rate = inside as f64 / trials as f64;
        assert!((rate - (1.0 - libm::exp(-1.0))).abs() < 0.03, "{rate}");
        assert!(h1_uncertainty(truth, 1.0, blocks) == 0.0);
        assert!(h1_uncertainty(truth, 0.5, 1).is_infinite());
    }

    /// The noise beside a periodic excitation's bin states its uncertainty: over many noisy
    /// records of a known system the truth lies inside the radius about 63 % of the time.
    #[test]
    fn periodic_uncertainty_covers_the_truth_at_its_stated_rate() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let (cycles, n) = (40usize, 1600usize);
        let truth = Complex64::from_polar(3.0e-6, 0.4);
        let w = 2.0 * std::f64::consts::PI * cycles as f64 / n as f64;
        let u: Vec<f64> = (0..n).map(|k| libm::cos(w * k as f64)).collect();
        let trials = 3000;
        let mut inside = 0;
        for _ in 0..trials {
            let y: Vec<f64> = (0..n)
                .map(|k| {
                    truth.norm() * libm::cos(w * k as f64 + truth.arg())
                        + 2.0e-5 * (rng.random::<f64>() - 0.5)
                })
                .collect();
            let h = dft_bin(&y, cycles) / dft_bin(&u, cycles);
            if (h - truth).norm() <= periodic_uncertainty(&u, &y, cycles, 4) {
                inside += 1;
            }
        }
        let rate = inside as f64 / trials as f64;
        assert!((rate - (1.0 - libm::exp(-1.0))).abs() < 0.03, "{rate}");
    }

    #[test]
    fn exact_bin_recovers_amplitude_and_phase() {
        let (n, cycles, amp, phase) = (8192usize, 37usize, 1.7e-9, -0.83);
        let x: Vec<f64> = (0..n)
            .map(|k| {
                amp * libm::cos(
                    2.0 * std::f64::consts::PI * cycles as f64 * k as f64 / n as f64 + phase,
                ) + 4e-9
            })
            .collect();
        let c = dft_bin(&x, cycles);
        assert!((c.norm() - amp).abs() < 1e-12 * amp);
        assert!((c.arg() - phase).abs() < 1e-12);
    }

    /// A stepped sine's longest record (a 20 Hz point: 32 periods at 199.6 kHz, 319 360
    /// samples, not a multiple of the anchor): the rotated twiddles agree with the sum over
    /// exact twiddles at every bin the uncertainty reads, to rounding.
    #[test]
    fn rotated_twiddles_agree_with_exact_ones_on_a_long_record() {
        use rand::{Rng, SeedableRng};
        let n = 319_360usize;
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let x: Vec<f64> = (0..n)
            .map(|k| libm::cos(2e-4 * k as f64) + rng.random::<f64>() - 0.5)
            .collect();
        for cycles in [1usize, 28, 32, 36, n / 2 - 1] {
            let exact = x
                .iter()
                .enumerate()
                .fold(Complex64::new(0.0, 0.0), |acc, (k, &v)| {
                    let r = (k as u128 * cycles as u128 % n as u128) as f64;
                    acc + v * Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * r / n as f64)
                })
                * (2.0 / n as f64);
            let fast = dft_bin(&x, cycles);
            // The sum's own rounding (n·ε of the samples' magnitude) bounds both.
            assert!((fast - exact).norm() < 1e-12, "{cycles}: {fast} vs {exact}");
        }
    }
}
