//! A loop response known at every frequency from one measured at some: the model corrected by
//! the measurement inside the band, the model with an allowance beyond it.

use num_complex::Complex64;

/// Smallest relative uncertainty assumed for the model beyond the measured band.
const MIN_BEYOND: f64 = 0.05;

/// Bins at the top of the band whose disagreement with the model sets the allowance beyond it.
const TOP_BINS: usize = 10;

/// A loop response known at every frequency from a measured one: at the measured bins the
/// measurement, between them the model times the measured-to-model ratio interpolated (in log
/// frequency), below the first bin that ratio held; beyond the last bin the model, known within
/// `beyond` of its magnitude — the largest relative disagreement between measurement and model
/// (plus the measurement's own uncertainty) over the band's top bins, at least 5 %:
/// an FRF stops where it was measured, and a check beyond it errs safe.
#[derive(Debug, Clone)]
pub struct Extended {
    freq_hz: Vec<f64>,
    /// Measured over model at each bin, and the measurement's radius over the model's magnitude.
    ratio: Vec<(Complex64, f64)>,
    /// Relative radius assumed beyond the last bin.
    pub beyond: f64,
    /// The last measured frequency, Hz.
    pub top_hz: f64,
}

impl Extended {
    /// The measured `(response, radius)` at `freq_hz` beside the model's `model(f)`.
    pub fn new(
        freq_hz: &[f64],
        measured: &[(Complex64, f64)],
        model: &dyn Fn(f64) -> Complex64,
    ) -> Self {
        let ratio: Vec<(Complex64, f64)> = freq_hz
            .iter()
            .zip(measured)
            .map(|(&f, &(g, sigma))| {
                let m = model(f);
                (g / m, sigma / m.norm())
            })
            .collect();
        let beyond = ratio
            .iter()
            .rev()
            .take(TOP_BINS)
            .map(|(r, rho)| (r - 1.0).norm() + rho)
            .fold(MIN_BEYOND, f64::max);
        Extended {
            freq_hz: freq_hz.to_vec(),
            top_hz: freq_hz.last().copied().unwrap_or(0.0),
            ratio,
            beyond,
        }
    }

    /// The response and the radius it is known within at `f_hz`, the model there `model_at`.
    pub fn at(&self, f_hz: f64, model_at: Complex64) -> (Complex64, f64) {
        let f = &self.freq_hz;
        let (r, rho) = match f.iter().position(|&x| x >= f_hz) {
            None => return (model_at, self.beyond * model_at.norm()),
            Some(0) => self.ratio[0],
            Some(k) => {
                let ln = libm::log;
                let t = (ln(f_hz) - ln(f[k - 1])) / (ln(f[k]) - ln(f[k - 1]));
                let (a, b) = (self.ratio[k - 1], self.ratio[k]);
                (a.0 + (b.0 - a.0) * t, a.1 + (b.1 - a.1) * t)
            }
        };
        (model_at * r, model_at.norm() * rho)
    }
}
