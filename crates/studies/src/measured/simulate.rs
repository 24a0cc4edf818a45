//! A part cut and measured in simulation, so the measure → register → compensate loop runs
//! end to end here: the part the run's tool path leaves over the whole aperture — the loop's
//! steady-state error at each ring through the stage the run simulates (the practice stage's
//! linear loop, its hidden parameters and modes included, when `[run] practice_seed` is set;
//! else the configured stage), a `[compensation]`'s move of the path, and the machine's tool
//! setting errors (configured plus the practice stage's hidden ones) — sampled by a simulated
//! instrument ([`metrology::Instrument`]). What a linear steady state leaves out (the
//! practice stage's force constant over the stroke and its drifting suspension, noise, the
//! cutting force, the feed marks) is not in the part: a whole-aperture cut in the time domain
//! is ~2 000 revolutions.

use super::PART_NODES;
use crate::error::StudyError;
use crate::toolpath::demands::{prescription_of, RingLoop};
use crate::toolpath::predicted_part;
use loop_model::closed_loop::ClosedLoop;
use metrology::{form_of, ApertureMap, Form, Instrument, MeasuredMap, Mounting};
use optics::Prescription;
use runner::Plan;
use serde::Serialize;
use std::f64::consts::TAU;

/// Nodes per side of the part's error map the instrument samples.
const ERROR_NODES: usize = 2 * PART_NODES - 1;

/// A simulated measurement and the truth it was made from.
#[derive(Debug, Clone, Serialize)]
pub struct SimulatedMeasurement {
    /// The stage the part was cut on.
    pub stage: String,
    /// The part's error against the design as cut (the truth).
    pub part: Form,
    /// The machine's tool centre height and X offset (the truth), m.
    pub tool_setting_m: [f64; 2],
    /// The instrument.
    pub instrument: Instrument,
    /// How the part was mounted on it (the truth).
    pub mounting: Mounting,
    /// The map the instrument returned.
    #[serde(skip)]
    pub map: MeasuredMap,
}

/// Cuts `plan`'s prescription in simulation and measures it with `instrument`, mounted with
/// a pose drawn from `seed`.
pub fn simulate_measurement(
    plan: &Plan,
    instrument: &Instrument,
    seed: u64,
) -> Result<SimulatedMeasurement, StudyError> {
    let (m, path, _) = prescription_of(plan)?;
    let aperture = path.prescription().aperture_radius_m;
    let (closed_loop, stage) = match plan.config.run.practice_seed {
        Some(s) => {
            let practice = run_config::practice_stage(&plan.config, &plan.origin, s)?;
            let tick = practice
                .simulator()
                .linear_tick()
                .ok_or(StudyError::NeedsLinearPlant {
                    what: "a simulated measurement",
                })?;
            (
                ClosedLoop::new(
                    &tick,
                    &plan.controller.linear,
                    plan.config.plant.capa.sensitivity_v_per_m,
                    plan.sim.period_s(),
                ),
                format!("the practice stage of seed {s} (its linear loop)"),
            )
        }
        None => (plan.closed_loop.clone(), "the configured stage".to_string()),
    };
    let ring_loop = RingLoop::of(&closed_loop, plan, m.rad_per_s() / TAU);
    let servo = predicted_part(path, &ring_loop);
    let setting = m.tool_setting_m(&plan.config.run);
    let error = |x: f64, y: f64| {
        let s = path.setting_error_m(libm::hypot(x, y), libm::atan2(y, x), setting[0], setting[1]);
        servo(x, y) + if s.is_finite() { s } else { 0.0 }
    };
    let part = form_of(
        &ApertureMap::of(PART_NODES, aperture, error).points(),
        aperture,
    );
    // A margin beyond the aperture, so that interpolation at its edge has neighbours.
    let fine = ApertureMap::of(ERROR_NODES, aperture * 1.02, error);
    let design = Prescription {
        compensation: None,
        ..path.prescription().clone()
    };
    let (map, mounting) =
        instrument.measure(|x, y| -design.sag(x, y).z_m + fine.at(x, y), aperture, seed);
    Ok(SimulatedMeasurement {
        stage,
        part,
        tool_setting_m: setting,
        instrument: *instrument,
        mounting,
        map,
    })
}
