//! Points of an FRF the grey-box model cannot explain: found by their relative residual
//! standing out of the fit's (robust scale: the median), left out, the fit repeated until the
//! set no longer changes; grouped into bands to report.

use num_complex::Complex64;

/// A band of consecutive FRF points whose relative residual stands out of the fit's.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Misfit {
    /// First point's frequency, Hz.
    pub from_hz: f64,
    /// Last point's frequency, Hz.
    pub to_hz: f64,
    /// The frequency of its worst point, Hz.
    pub worst_hz: f64,
    /// Points in the band.
    pub points: usize,
    /// The largest deviation in the band, measured over model, dB.
    pub worst_db: f64,
    /// The largest relative residual |G − Ĝ|/|G| in the band.
    pub worst_relative: f64,
}

/// A point is a misfit when its relative residual exceeds this many robust standard
/// deviations (1.4826 × the median residual) of the points kept …
pub const MISFIT_SIGMAS: f64 = 6.0;
/// … and this relative residual (measurement noise alone never reaches it: 3 %).
pub const MISFIT_MIN_RELATIVE: f64 = 0.03;
/// Rounds of fitting, leaving misfits out, and refitting.
const MISFIT_ROUNDS: usize = 4;

/// The runs of consecutive points left out (`keep` false), with their worst deviation
/// (`residual`: measured over fitted model).
pub(super) fn misfit_bands(freq_hz: &[f64], keep: &[bool], residual: &[Complex64]) -> Vec<Misfit> {
    let mut bands: Vec<Misfit> = Vec::new();
    for i in (0..freq_hz.len()).filter(|&i| !keep[i]) {
        let relative = (residual[i] - 1.0).norm();
        let db = 20.0 * libm::log10(residual[i].norm());
        match bands.last_mut() {
            Some(b) if i > 0 && !keep[i - 1] => {
                b.to_hz = freq_hz[i];
                b.points += 1;
                if relative > b.worst_relative {
                    (b.worst_relative, b.worst_db, b.worst_hz) = (relative, db, freq_hz[i]);
                }
            }
            _ => bands.push(Misfit {
                from_hz: freq_hz[i],
                to_hz: freq_hz[i],
                worst_hz: freq_hz[i],
                points: 1,
                worst_db: db,
                worst_relative: relative,
            }),
        }
    }
    bands
}

/// The relative residuals `|G/Ĝ − 1|` of `measured` against `fitted`.
pub(super) fn relative_residuals(measured: &[Complex64], fitted: &[Complex64]) -> Vec<f64> {
    measured
        .iter()
        .zip(fitted)
        .map(|(g, m)| (g / m - 1.0).norm())
        .collect()
}

/// Which points to keep after a fit with relative residuals `relative`, of which those in
/// `keep` were fitted: the others stand out of the kept points' robust scale by more than
/// [`MISFIT_SIGMAS`] and [`MISFIT_MIN_RELATIVE`].
pub(super) fn kept_after(relative: &[f64], keep: &[bool]) -> Vec<bool> {
    let mut kept: Vec<f64> = (0..relative.len())
        .filter(|&i| keep[i])
        .map(|i| relative[i])
        .collect();
    kept.sort_by(f64::total_cmp);
    let sigma = 1.4826 * kept.get(kept.len() / 2).copied().unwrap_or(0.0);
    let limit = (MISFIT_SIGMAS * sigma).max(MISFIT_MIN_RELATIVE);
    relative.iter().map(|r| *r <= limit).collect()
}

/// Fits with `fit` (on the kept frequencies and responses; returns its result and the model
/// at every frequency), leaves out the points it cannot explain and fits again, up to
/// [`MISFIT_ROUNDS`] times; the last fit, the points kept, the model at every point.
pub(super) fn fit_excluding<F>(
    freq_hz: &[f64],
    measured: &[Complex64],
    min_points: usize,
    mut fit: impl FnMut(&[f64], &[Complex64]) -> Result<(F, Vec<Complex64>), crate::StudyError>,
) -> Result<(F, Vec<bool>, Vec<Complex64>), crate::StudyError> {
    let mut keep = vec![true; freq_hz.len()];
    let mut round = 0;
    loop {
        let (kf, km): (Vec<f64>, Vec<Complex64>) = (0..freq_hz.len())
            .filter(|&i| keep[i])
            .map(|i| (freq_hz[i], measured[i]))
            .unzip();
        let (f, fitted) = fit(&kf, &km)?;
        let next = kept_after(&relative_residuals(measured, &fitted), &keep);
        round += 1;
        let usable = next.iter().filter(|k| **k).count() >= min_points;
        if next == keep || !usable || round == MISFIT_ROUNDS {
            return Ok((f, keep, fitted));
        }
        keep = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_of_outliers_is_one_band_with_its_worst_point() {
        let f: Vec<f64> = (1..=10).map(|i| 100.0 * i as f64).collect();
        let mut relative = vec![
            0.002, 0.003, 0.001, 0.002, 0.004, 0.002, 0.003, 0.002, 0.001, 0.002,
        ];
        relative[5] = 0.5;
        relative[6] = 0.1;
        let keep = kept_after(&relative, &[true; 10]);
        assert_eq!(keep.iter().filter(|k| !**k).count(), 2);
        let residual: Vec<Complex64> = relative
            .iter()
            .map(|r| Complex64::new(1.0 + r, 0.0))
            .collect();
        let bands = misfit_bands(&f, &keep, &residual);
        assert_eq!(bands.len(), 1);
        let b = &bands[0];
        assert_eq!((b.from_hz, b.to_hz, b.points), (600.0, 700.0, 2));
        assert!((b.worst_db - 20.0 * libm::log10(1.5f64)).abs() < 1e-12);
        // Noise alone (all below 3 %) leaves everything in.
        assert!(kept_after(&[0.01, 0.02, 0.029, 0.001], &[true; 4])
            .iter()
            .all(|k| *k));
    }
}
