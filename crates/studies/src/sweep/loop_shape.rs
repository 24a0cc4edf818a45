//! A PID shaped for a loop-gain crossover by the rule of thumb thesis §5.6 points to (its
//! footnote 11: JPE, "Motion control basic feedback design"): for a mass-like plant, the
//! integrator's zero a decade below the crossover `f_c`, the differentiator's zero at `f_c/3`
//! and its roll-off at `3·f_c` (≈ 53° of phase lead at `f_c`), and the gain that makes
//! `|L(j2πf_c)| = 1` on the exact sampled plant (delay, hold, ADC mean and sensor included).

use super::Plan;
use crate::error::StudyError;
use crate::tune::{pid_basis, plant_response};
use run_config::PidGains;
use std::f64::consts::PI;

/// Integrator zero below the crossover (factor).
const INTEGRATOR_BELOW: f64 = 10.0;
/// Differentiator zero below, and its roll-off above, the crossover (factor).
const LEAD_SPREAD: f64 = 3.0;

/// The PID `K (1 + ωi/s)(1 + s/ωd)/(1 + s/ωt)` with `ωi = ωc/10`, `ωd = ωc/3`, `ωt = 3ωc`,
/// written in the parallel form of eq 7-8 (`kp + ki/s + kd·s/(tf·s + 1)`), `K` giving unit loop
/// gain at `crossover_hz` (Hz) on the sampled plant of `plan`.
pub fn loop_shaped(plan: &Plan, crossover_hz: f64) -> Result<PidGains, StudyError> {
    let wc = 2.0 * PI * crossover_hz;
    let (wi, wd, wt) = (wc / INTEGRATOR_BELOW, wc / LEAD_SPREAD, wc * LEAD_SPREAD);
    // Series → parallel: tf = 1/ωt, ki = K ωi, kp = K (1 + ωi/ωd − ωi/ωt), kd = K/ωd − kp tf.
    let tf_s = 1.0 / wt;
    let unit_kp = 1.0 + wi / wd - wi / wt;
    let unit = [unit_kp, wi, 1.0 / wd - unit_kp * tf_s];
    let f = [crossover_hz];
    let plant = plant_response(plan, &f)?[0];
    let b = pid_basis(plan, &f, tf_s)?[0];
    let l = plant * (b[0] * unit[0] + b[1] * unit[1] + b[2] * unit[2]);
    let k = 1.0 / l.norm();
    Ok(PidGains {
        kp: k * unit[0],
        ki: k * unit[1],
        kd: k * unit[2],
        tf_s,
    })
}
