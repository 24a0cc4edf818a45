//! Spindle error separation by the complementary three-probe method (thesis Appendix D):
//! three displacement probes at 0, α and β around a rotating artefact see the artefact's form
//! `A(θ)` shifted by their angles plus the spindle's radial motion `X, Y` projected on them
//! (eq D-1..D-3). The weighted sum `S = S1 + a·S2 + b·S3` (eq D-4..D-6) cancels the motion and
//! leaves `A` filtered by the harmonic weighting `H(k)` (eq D-7), which is inverted harmonic by
//! harmonic; `X` follows from probe 1, `Y` from probe 2. Harmonics where `|H(k)|` is small are
//! amplified noise, so three angle sets are measured and combined: by the thesis's
//! frequency-domain modification (each set's magnitude clipped to the smallest of the three,
//! phase kept) or by least squares over the sets (weights `|H_i(k)|²`).
//!
//! ```
//! use design::spindle::{harmonic_weighting, THESIS_ANGLE_SETS};
//! // Eccentricity (1 UPR) is invisible to the method: H(1) = 0.
//! assert!(harmonic_weighting(&THESIS_ANGLE_SETS[0], 1).norm() < 1e-12);
//! ```

use num_complex::Complex64;
use realfft::RealFftPlanner;

/// Probe 2 and probe 3 angles from probe 1 (the X direction), counter-clockwise, in rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeAngles {
    /// α in rad.
    pub alpha_rad: f64,
    /// β in rad.
    pub beta_rad: f64,
}

/// Table D-1: the three designed angle sets (degrees converted to rad).
pub const THESIS_ANGLE_SETS: [ProbeAngles; 3] = [
    ProbeAngles {
        alpha_rad: 100.4 * DEG,
        beta_rad: 230.0333 * DEG,
    },
    ProbeAngles {
        alpha_rad: 141.0333 * DEG,
        beta_rad: 270.7050 * DEG,
    },
    ProbeAngles {
        alpha_rad: 139.3667 * DEG,
        beta_rad: 239.1200 * DEG,
    },
];

const DEG: f64 = std::f64::consts::PI / 180.0;

/// The weights `(a, b)` of eq D-5 and D-6.
pub fn weights(p: &ProbeAngles) -> (f64, f64) {
    let d = libm::sin(p.beta_rad - p.alpha_rad);
    (-libm::sin(p.beta_rad) / d, libm::sin(p.alpha_rad) / d)
}

/// `H(k) = 1 + a·e^{−jkα} + b·e^{−jkβ}` (eq D-7), k in undulations per revolution.
pub fn harmonic_weighting(p: &ProbeAngles, k: usize) -> Complex64 {
    let (a, b) = weights(p);
    let k = k as f64;
    1.0 + a * Complex64::from_polar(1.0, -k * p.alpha_rad)
        + b * Complex64::from_polar(1.0, -k * p.beta_rad)
}

/// The synchronous part of a signal sampled `per_rev` times per revolution: the mean over
/// the whole revolutions (asynchronous motion and noise average out).
pub fn synchronous(signal: &[f64], per_rev: usize) -> Vec<f64> {
    let revs = signal.len() / per_rev.max(1);
    (0..per_rev)
        .map(|i| (0..revs).map(|r| signal[r * per_rev + i]).sum::<f64>() / revs.max(1) as f64)
        .collect()
}

/// One angle set's separation: artefact form and spindle motion per sample of a revolution
/// (m), band-limited to harmonics `2..=max_harmonic`.
#[derive(Debug, Clone)]
pub struct Separation {
    /// The probe angles.
    pub angles: ProbeAngles,
    /// Artefact form error A(θ).
    pub artefact: Vec<f64>,
    /// Synchronous radial error motion along X.
    pub x: Vec<f64>,
    /// Synchronous radial error motion along Y.
    pub y: Vec<f64>,
    /// `S_k / H(k)` for k = 0..=max_harmonic (0 and 1 are undetermined and left zero).
    pub artefact_spectrum: Vec<Complex64>,
    /// `S1` band-limited, as a spectrum (for the motion once A is re-estimated).
    probe_spectra: [Vec<Complex64>; 2],
}

/// Forward real FFT of one revolution, scaled so that bin k is the complex amplitude of
/// `e^{jkθ}` (`x = Σ Re(c_k e^{jkθ})` for k ≥ 1 after doubling).
fn spectrum(x: &[f64]) -> Vec<Complex64> {
    let n = x.len();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = x.to_vec();
    let mut out = fft.make_output_vec();
    fft.process(&mut input, &mut out)
        .expect("sizes from the planner");
    out.into_iter().map(|c| c / n as f64).collect()
}

/// The revolution of `n` samples with the spectrum `c` (bins beyond `c.len()` zero).
fn waveform(c: &[Complex64], n: usize) -> Vec<f64> {
    let fft = RealFftPlanner::<f64>::new().plan_fft_inverse(n);
    let mut full = vec![Complex64::new(0.0, 0.0); n / 2 + 1];
    for (k, v) in c.iter().enumerate().take(full.len()) {
        full[k] = v * n as f64;
    }
    // The inverse of a real signal needs real DC and Nyquist bins.
    full[0].im = 0.0;
    if n.is_multiple_of(2) {
        full[n / 2].im = 0.0;
    }
    let mut out = vec![0.0; n];
    fft.process(&mut full, &mut out)
        .expect("sizes from the planner");
    out.into_iter().map(|v| v / n as f64).collect()
}

/// Keeps harmonics `2..=max_harmonic`.
fn band(mut c: Vec<Complex64>, max_harmonic: usize) -> Vec<Complex64> {
    c.truncate(max_harmonic + 1);
    for v in c.iter_mut().take(2) {
        *v = Complex64::new(0.0, 0.0);
    }
    c
}

/// Separates the synchronous probe signals `probes = [S1, S2, S3]` (one revolution each, the
/// same equally spaced angles, m) measured with `angles`.
pub fn separate(probes: [&[f64]; 3], angles: ProbeAngles, max_harmonic: usize) -> Separation {
    let n = probes[0].len();
    let (a, b) = weights(&angles);
    let weighted: Vec<f64> = (0..n)
        .map(|i| probes[0][i] + a * probes[1][i] + b * probes[2][i])
        .collect();
    let s = band(spectrum(&weighted), max_harmonic);
    let artefact_spectrum: Vec<Complex64> = s
        .iter()
        .enumerate()
        .map(|(k, v)| {
            if k < 2 {
                Complex64::new(0.0, 0.0)
            } else {
                v / harmonic_weighting(&angles, k)
            }
        })
        .collect();
    let probe_spectra = [
        band(spectrum(probes[0]), max_harmonic),
        band(spectrum(probes[1]), max_harmonic),
    ];
    with_artefact(angles, artefact_spectrum, probe_spectra, n)
}

/// The separation implied by an artefact spectrum: `X = S1 − A`,
/// `Y = (S2 − A(θ − α) − X cos α) / sin α`.
fn with_artefact(
    angles: ProbeAngles,
    artefact_spectrum: Vec<Complex64>,
    probe_spectra: [Vec<Complex64>; 2],
    n: usize,
) -> Separation {
    let x_spec: Vec<Complex64> = probe_spectra[0]
        .iter()
        .zip(&artefact_spectrum)
        .map(|(s, a)| s - a)
        .collect();
    let (ca, sa) = (libm::cos(angles.alpha_rad), libm::sin(angles.alpha_rad));
    let y_spec: Vec<Complex64> = (0..artefact_spectrum.len())
        .map(|k| {
            let shifted =
                artefact_spectrum[k] * Complex64::from_polar(1.0, -(k as f64) * angles.alpha_rad);
            (probe_spectra[1][k] - shifted - x_spec[k] * ca) / sa
        })
        .collect();
    Separation {
        angles,
        artefact: waveform(&artefact_spectrum, n),
        x: waveform(&x_spec, n),
        y: waveform(&y_spec, n),
        artefact_spectrum,
        probe_spectra,
    }
}

/// The thesis's frequency-domain modification (Appendix D.4): each set's artefact spectrum
/// keeps its phase, its magnitude is clipped to the smallest of all sets at that harmonic;
/// the motions are recomputed from the modified artefact.
pub fn modify(sets: &[Separation]) -> Vec<Separation> {
    let n = sets.first().map_or(0, |s| s.artefact.len());
    sets.iter()
        .map(|s| {
            let spec = s
                .artefact_spectrum
                .iter()
                .enumerate()
                .map(|(k, v)| {
                    let smallest = sets
                        .iter()
                        .map(|o| o.artefact_spectrum[k].norm())
                        .fold(f64::INFINITY, f64::min);
                    if v.norm() > 0.0 {
                        v * (smallest / v.norm())
                    } else {
                        *v
                    }
                })
                .collect();
            with_artefact(s.angles, spec, s.probe_spectra.clone(), n)
        })
        .collect()
}

/// Least-squares synthesis over the sets: `A_k = Σ H_i*(k) S_i,k / Σ |H_i(k)|²` (each set's
/// estimate weighted by `|H_i(k)|²`, the inverse of its noise gain), then the motions from the
/// first set's probes.
pub fn synthesise(sets: &[Separation]) -> Option<Separation> {
    let first = sets.first()?;
    let spec = (0..first.artefact_spectrum.len())
        .map(|k| {
            let (num, den) = sets
                .iter()
                .fold((Complex64::new(0.0, 0.0), 0.0), |(num, den), s| {
                    let h = harmonic_weighting(&s.angles, k);
                    // S_k = H·A_k, so H*·S_k = |H|²·A_k.
                    (
                        num + h.norm_sqr() * s.artefact_spectrum[k],
                        den + h.norm_sqr(),
                    )
                });
            if k < 2 || den == 0.0 {
                Complex64::new(0.0, 0.0)
            } else {
                num / den
            }
        })
        .collect();
    Some(with_artefact(
        first.angles,
        spec,
        first.probe_spectra.clone(),
        first.artefact.len(),
    ))
}
