//! Where an extra mode acts, from the accelerometer. A command → gap FRF cannot tell a mode of
//! the stage (on the motor force: the tool, the gap and the accelerometer on m2 all feel it)
//! from one on the gap reading (a sensor mount: only the reading moves) — both multiply the
//! same response. The accelerometer's FRF, measured with the same excitation (`servo frf`
//! writes it beside the gap's), can: a stage mode multiplies it by the mode's response too, a
//! mode on the reading leaves it as the model has it. Each mode is placed by which of the two
//! explains the accelerometer's bins where the mode moves the response (a χ² over them, each
//! bin weighted by its uncertainty); that matters to every design that predicts the tool from
//! the reading (ZPETC, the FIR, a tool-path prediction).

use crate::error::StudyError;
use loop_model::closed_loop::{input, output};
use num_complex::Complex64;
use plant_sim::modes::{ExtraMode, ModeSite};
use plant_sim::PlantParams;
use run_config::frf_file::MeasuredFrf;

/// A mode's bins are where it moves the response by more than this (relative).
const MOVES: f64 = 0.1;
/// Fewest bins a placement rests on.
const MIN_BINS: usize = 2;

/// Why a mode was placed where it is.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct SiteEvidence {
    /// The accelerometer bins the placement rests on.
    pub bins: usize,
    /// `Σ|A − A₀·N|²/σ²` over them: the mode on the motor force.
    pub chi2_force: f64,
    /// `Σ|A − A₀|²/σ²` over them: the mode on the reading.
    pub chi2_sensor: f64,
}

impl SiteEvidence {
    /// The evidence in words, for a report or a plant file's comment.
    pub fn describe(&self) -> String {
        let (seen, site) = if self.chi2_force < self.chi2_sensor {
            ("shows it", "on the motor force")
        } else {
            ("does not show it", "on the reading")
        };
        format!(
            "{site}: the accelerometer's FRF {seen} (χ² over {} bins: {:.3e} as a stage mode, {:.3e} as a mode on the reading)",
            self.bins, self.chi2_force, self.chi2_sensor
        )
    }
}

/// Where a mode is and why, in words: the evidence, or that it was left on the reading
/// unplaced.
pub fn describe_site(site: &Option<SiteEvidence>) -> String {
    match site {
        Some(e) => e.describe(),
        None => {
            "on the reading (not placed: no accelerometer FRF, or fewer than two of its bins move)"
                .into()
        }
    }
}

/// Places each of `modes` (fitted on the reading) on the motor force where the accelerometer's
/// FRF of `frf` says so, against `plant` (the model without `modes`): the evidence for each, or
/// None where the file has no accelerometer FRF or the mode moves fewer than two of its bins.
pub fn place_modes(
    plant: &PlantParams,
    modes: &mut [ExtraMode],
    frf: &MeasuredFrf,
) -> Result<Vec<Option<SiteEvidence>>, StudyError> {
    let Some(accel) = &frf.accel else {
        return Ok(vec![None; modes.len()]);
    };
    let freq_hz = &frf.freq_hz;
    let open = super::open_model(plant)
        .map_err(|e| StudyError::from(design::identify::IdentifyError::Invalid(e)))?;
    let model: Vec<Complex64> = freq_hz
        .iter()
        .map(|&f| open.response(output::ACCEL_READING_V, input::CONTROL_DISTURBANCE_V, f))
        .collect::<Result<_, _>>()?;
    Ok(modes
        .iter_mut()
        .map(|mode| {
            let (mut bins, mut chi2_force, mut chi2_sensor) = (0, 0.0, 0.0);
            for (i, &f) in freq_hz.iter().enumerate() {
                let n = mode.response(f);
                let sigma = accel.uncertainty[i];
                if (n - 1.0).norm() < MOVES || !(sigma > 0.0 && sigma.is_finite()) {
                    continue;
                }
                let a = accel.response[i];
                bins += 1;
                chi2_force += ((a - model[i] * n).norm() / sigma).powi(2);
                chi2_sensor += ((a - model[i]).norm() / sigma).powi(2);
            }
            (bins >= MIN_BINS).then(|| {
                if chi2_force < chi2_sensor {
                    mode.at = ModeSite::Force;
                }
                SiteEvidence {
                    bins,
                    chi2_force,
                    chi2_sensor,
                }
            })
        })
        .collect())
}
