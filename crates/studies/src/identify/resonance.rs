//! A resonance the four-mass model does not contain (a sensor mount, a part of the frame),
//! found as a misfit band and fitted there as a second-order factor on the model's response,
//! `N(s) = (s² + 2ζz·ωz·s + ωz²)/(s² + 2ζp·ωp·s + ωp²) · ωp²/ωz²` (unit gain at DC), together
//! with the stage parameters — so that it is reported with its frequency and damping instead of
//! pulling the Table 5-2 parameters toward it. The identified model file does not contain it.

use super::misfit::Misfit;
use crate::StudyError;
use num_complex::Complex64;

/// The fitted resonance.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ExtraResonance {
    /// Pole pair frequency, Hz.
    pub pole_hz: f64,
    /// Pole pair damping ratio.
    pub pole_zeta: f64,
    /// Zero pair frequency, Hz.
    pub zero_hz: f64,
    /// Zero pair damping ratio.
    pub zero_zeta: f64,
    /// Its largest effect on the response, dB (at the pole frequency).
    pub peak_db: f64,
}

/// Damping ratios the fit may take.
const ZETA_RANGE: (f64, f64) = (1e-3, 0.7);
/// How far outside its misfit band the resonance may move (a factor on frequency).
const BAND_MARGIN: f64 = 1.3;

/// `N(j2πf)` of parameters `[pole_hz, pole_zeta, zero_hz, zero_zeta]`.
pub(super) fn factor(p: &[f64], f_hz: f64) -> Complex64 {
    let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
    let w = |hz: f64| 2.0 * std::f64::consts::PI * hz;
    let (wp, wz) = (w(p[0]), w(p[2]));
    (s * s + 2.0 * p[3] * wz * s + wz * wz) / (s * s + 2.0 * p[1] * wp * s + wp * wp) * (wp * wp)
        / (wz * wz)
}

/// Start and bounds of the resonance in misfit `band`, whose worst point's measured-over-model
/// ratio is `worst` (a peak of ζz/ζp when the zeros sit at the poles).
pub(super) fn start_and_bounds(band: &Misfit, worst: f64) -> ([f64; 4], [f64; 4], [f64; 4]) {
    let zeta_p = 0.02;
    let zeta_z = (zeta_p * worst).clamp(ZETA_RANGE.0, ZETA_RANGE.1);
    let (lo_hz, hi_hz) = (band.from_hz / BAND_MARGIN, band.to_hz * BAND_MARGIN);
    (
        [band.worst_hz, zeta_p, band.worst_hz, zeta_z],
        [lo_hz, ZETA_RANGE.0, lo_hz, ZETA_RANGE.0],
        [hi_hz, ZETA_RANGE.1, hi_hz, ZETA_RANGE.1],
    )
}

impl ExtraResonance {
    /// The resonance of fitted parameters `p` (`[pole_hz, pole_zeta, zero_hz, zero_zeta]`).
    pub(super) fn of(p: &[f64]) -> Self {
        ExtraResonance {
            pole_hz: p[0],
            pole_zeta: p[1],
            zero_hz: p[2],
            zero_zeta: p[3],
            peak_db: 20.0 * libm::log10(factor(p, p[0]).norm()),
        }
    }
}

/// Checks that the fitted resonance lies where the misfit was (not a stand-in for something
/// the stage parameters should explain).
pub(super) fn plausible(r: &ExtraResonance, band: &Misfit) -> Result<(), StudyError> {
    let inside = |hz: f64| hz >= band.from_hz / BAND_MARGIN && hz <= band.to_hz * BAND_MARGIN;
    if inside(r.pole_hz) && inside(r.zero_hz) {
        Ok(())
    } else {
        Err(design::identify::IdentifyError::Invalid(format!(
            "the resonance fitted for the misfit at {:.0} – {:.0} Hz moved to its bounds",
            band.from_hz, band.to_hz
        ))
        .into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dipole (zeros at the poles): unit gain at DC and far above, ζz/ζp at the poles.
    #[test]
    fn a_dipole_peaks_by_the_damping_ratio() {
        let p = [5000.0, 0.01, 5000.0, 0.02];
        assert!((factor(&p, 5000.0).norm() - 2.0).abs() < 1e-12);
        assert!((factor(&p, 1.0).norm() - 1.0).abs() < 1e-6);
        assert!((factor(&p, 1e6).norm() - 1.0).abs() < 1e-3);
        assert!((ExtraResonance::of(&p).peak_db - 20.0 * libm::log10(2f64)).abs() < 1e-9);
    }
}
