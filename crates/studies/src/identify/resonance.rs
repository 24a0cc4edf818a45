//! A resonance the four-mass model does not contain (a sensor mount, a part of the frame),
//! found as a misfit band and fitted there as an extra mode on the model's response
//! ([`plant_sim::modes::ExtraMode`]: a pole and a zero pair, unit gain at DC), together with
//! the stage parameters — so that it is reported with its frequency and damping instead of
//! pulling the Table 5-2 parameters toward it, and carried into the identified model file.
//!
//! A command → gap FRF cannot tell a mode on the reading from a mode of the stage (both multiply
//! the same response); the mode is written on the reading (`at = "sensor"`), which every design
//! and loop check sees alike — only the predicted tool motion would differ.

use super::misfit::Misfit;
use crate::StudyError;
use plant_sim::modes::ExtraMode;

/// Damping ratios the fit may take.
pub(super) const ZETA_RANGE: (f64, f64) = (1e-3, 0.7);
/// How far outside its misfit band the resonance may move (a factor on frequency).
const BAND_MARGIN: f64 = 1.3;

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

/// Checks that the fitted resonance lies where the misfit was (not a stand-in for something
/// the stage parameters should explain).
pub(super) fn plausible(r: &ExtraMode, band: &Misfit) -> Result<(), StudyError> {
    let inside = |hz: f64| hz >= band.from_hz / BAND_MARGIN && hz <= band.to_hz * BAND_MARGIN;
    if inside(r.hz) && inside(r.zero_hz) {
        Ok(())
    } else {
        Err(design::identify::IdentifyError::Invalid(format!(
            "the resonance fitted for the misfit at {:.0} – {:.0} Hz moved to its bounds",
            band.from_hz, band.to_hz
        ))
        .into())
    }
}
