//! Gain and phase margins of a plan's loop broken at the actuator input.

use crate::error::StudyError;
use runner::closed_loop::ClosedLoop;
use runner::Plan;

/// Gain and phase margins of the loop of `plan` broken at the actuator input (the sampled
/// plant from DAC command to gap reading, times the controller's gap channel), searched from
/// 1 Hz to Nyquist. Acceleration feedback's inner loop is not part of this break.
pub fn loop_margins(plan: &Plan) -> Result<design::loops::Margins, StudyError> {
    let s = plan.config.plant.capa.sensitivity_v_per_m;
    let period = plan.period_s();
    let open = ClosedLoop::open(&plan.sim, s).ok_or(StudyError::NeedsLinearPlant {
        what: "the margins",
    })?;
    let k = &plan.controller.linear;
    let k_gap = lti::StateSpace {
        a: k.a.clone(),
        b: k.b.columns(0, 1).into_owned(),
        c: k.c.clone(),
        d: k.d.columns(0, 1).into_owned(),
    };
    let loop_gain = |f: f64| {
        let p = open.command_response(f).unwrap_or_default() * s;
        let kk = k_gap
            .freq_response_discrete(f, period)
            .map(|m| m[(0, 0)])
            .unwrap_or_default();
        -(kk * p)
    };
    Ok(design::loops::margins(loop_gain, 1.0, 0.499 / period))
}
