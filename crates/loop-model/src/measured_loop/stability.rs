//! The feedback loop's stability on a measured FRF: margins, sensitivity peak, and whether
//! every loop within the measurement's uncertainty disks is stable.
//!
//! The model's closed loop is checked stable (`runner::Plan::check_stable`); the loop on the
//! measured FRF has the same open-loop poles (the same controller, a stage measured in open
//! loop, hence stable), so it is stable when its Nyquist plot encircles −1 as often as the
//! model's: when the phase of `(1 + L_measured)/(1 + L_model)` returns between 1 Hz and Nyquist
//! to where it started (the two coincide beyond the measured band). Every loop within the
//! disks `|ΔL| ≤ r` is then stable when `|1 + L| > r` at every frequency (none of them can
//! reach −1 on the way from the measured one).

use super::extended::Extended;
use num_complex::Complex64;

/// The lowest frequency looked at, Hz.
const F_LO_HZ: f64 = 1.0;
/// Points of the log grid (besides the measured bins) on which the loop is checked.
const GRID_POINTS: usize = 4000;

/// The feedback loop closed on a measured FRF.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredStability {
    /// Gain and phase margins of the measured loop gain from 1 Hz to Nyquist (between bins and
    /// beyond the band as [`Extended`] fills it).
    pub margins: design::loops::Margins,
    /// The loop with the controller's output as it is.
    pub verdict: Verdict,
    /// The last measured frequency, Hz.
    pub top_hz: f64,
    /// The relative radius allowed for the model beyond `top_hz`.
    pub beyond: f64,
    /// The loop gain on the check's grid.
    samples: Vec<Sample>,
}

/// The loop on the measurement, the controller's output scaled by some factor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    /// The measured loop encircles −1 as often as the model's at the same scale.
    pub stable: bool,
    /// The smallest `|1 + L| − r` over frequency, `r` the radius the loop gain is known within
    /// (each bin's uncertainty disk; beyond the band the allowance [`Extended::beyond`]), and
    /// where, Hz.
    pub disk_distance: (f64, f64),
    /// The peak of the sensitivity `|1/(1 + L)|`, dB, and where, Hz.
    pub sensitivity_peak: (f64, f64),
}

impl Verdict {
    /// Every loop the measurement allows (within each bin's disk) has the model's number of
    /// encirclements of −1.
    pub fn robustly_stable(&self) -> bool {
        self.stable && self.disk_distance.0 > 0.0
    }
}

/// The loop gain at one frequency of the check's grid.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    f_hz: f64,
    /// On the measurement, and the radius it is known within.
    measured: (Complex64, f64),
    /// On the model.
    model: Complex64,
}

impl MeasuredStability {
    /// The loop gain measured at `freq_hz` as `(L, radius)`, the model's `model(f)`, checked up
    /// to `nyquist_hz`.
    pub(super) fn of(
        freq_hz: &[f64],
        measured: &[(Complex64, f64)],
        model: &dyn Fn(f64) -> Complex64,
        nyquist_hz: f64,
    ) -> Self {
        let extended = Extended::new(freq_hz, measured, model);
        let at = |f: f64| extended.at(f, model(f));
        let margins = design::loops::margins(|f| at(f).0, F_LO_HZ, nyquist_hz);
        let mut grid = lti::spectral::log_space(F_LO_HZ, nyquist_hz, GRID_POINTS);
        grid.extend(freq_hz.iter().filter(|&&f| f > F_LO_HZ && f < nyquist_hz));
        grid.sort_by(f64::total_cmp);
        let samples: Vec<Sample> = grid
            .into_iter()
            .map(|f_hz| Sample {
                f_hz,
                measured: at(f_hz),
                model: model(f_hz),
            })
            .collect();
        MeasuredStability {
            margins,
            verdict: verdict(&samples, 1.0),
            top_hz: extended.top_hz,
            beyond: extended.beyond,
            samples,
        }
    }

    /// The loop with the controller's output multiplied by `scale`.
    pub fn at_scale(&self, scale: f64) -> Verdict {
        verdict(&self.samples, scale)
    }
}

/// The loop of `samples`, scaled by `scale`.
fn verdict(samples: &[Sample], scale: f64) -> Verdict {
    let mut peak = (f64::NEG_INFINITY, F_LO_HZ);
    let mut distance = (f64::INFINITY, F_LO_HZ);
    let (mut winding, mut last_phase) = (0.0, None);
    for s in samples {
        let (l, r) = (s.measured.0 * scale, s.measured.1 * scale);
        let gap = (1.0 + l).norm();
        let db = -20.0 * libm::log10(gap);
        if db > peak.0 {
            peak = (db, s.f_hz);
        }
        if gap - r < distance.0 {
            distance = (gap - r, s.f_hz);
        }
        let phase = ((1.0 + l) / (1.0 + s.model * scale)).arg();
        if let Some(p) = last_phase {
            winding += wrapped(phase - p);
        }
        last_phase = Some(phase);
    }
    Verdict {
        stable: libm::fabs(winding) < core::f64::consts::PI,
        disk_distance: distance,
        sensitivity_peak: peak,
    }
}

/// `x` (rad) brought into (−π, π].
fn wrapped(x: f64) -> f64 {
    let tau = core::f64::consts::TAU;
    x - tau * libm::round(x / tau)
}
