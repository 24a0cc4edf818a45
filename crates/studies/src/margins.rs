//! Gain and phase margins of a plan's loop broken at the actuator input.

use crate::error::StudyError;
use loop_model::closed_loop::ClosedLoop;
use runner::Plan;

/// Gain and phase margins of the loop of `plan` broken at the actuator input
/// ([`ClosedLoop::loop_gain`]: `L = −(K_gap·P_gap + K_acc·P_acc)`, with acceleration feedback
/// its inner loop part of the break), searched from 1 Hz to Nyquist.
pub fn loop_margins(plan: &Plan) -> Result<design::loops::Margins, StudyError> {
    let s = plan.config.plant.capa.sensitivity_v_per_m;
    let period = plan.period_s();
    let open = ClosedLoop::open(&plan.sim, s).ok_or(StudyError::NeedsLinearPlant {
        what: "the margins",
    })?;
    let l = lti::FrequencyResponse::new(&open.loop_gain(&plan.controller.linear, s)?);
    let loop_gain = |f: f64| {
        l.discrete(f, period)
            .map_or_else(|_| num_complex::Complex64::default(), |h| h[(0, 0)])
    };
    Ok(design::loops::margins(loop_gain, 1.0, 0.499 / period))
}
