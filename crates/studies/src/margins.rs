//! Gain and phase margins of a plan's loop broken at the actuator input.

use crate::error::StudyError;
use runner::closed_loop::{input, output, ClosedLoop};
use runner::Plan;

/// Gain and phase margins of the loop of `plan` broken at the actuator input: the sampled
/// plant from DAC command to both readings (gap and accelerometer) times the controller's two
/// channels, `L = −(K_gap·P_gap + K_acc·P_acc)` — with acceleration feedback its inner loop is
/// part of the break — searched from 1 Hz to Nyquist.
pub fn loop_margins(plan: &Plan) -> Result<design::loops::Margins, StudyError> {
    let s = plan.config.plant.capa.sensitivity_v_per_m;
    let period = plan.period_s();
    let open = ClosedLoop::open(&plan.sim, s).ok_or(StudyError::NeedsLinearPlant {
        what: "the margins",
    })?;
    let k = &plan.controller.linear;
    let k = lti::StateSpace {
        a: k.a.clone(),
        b: k.b.clone(),
        c: k.c.clone(),
        d: k.d.clone(),
    };
    let loop_gain = |f: f64| {
        let p_gap = open.command_response(f).unwrap_or_default() * s;
        let p_acc = open
            .response(output::ACCEL_READING_V, input::CONTROL_DISTURBANCE_V, f)
            .unwrap_or_default();
        let Ok(kk) = k.freq_response_discrete(f, period) else {
            return num_complex::Complex64::default();
        };
        -(kk[(0, 0)] * p_gap + kk[(0, 1)] * p_acc)
    };
    Ok(design::loops::margins(loop_gain, 1.0, 0.499 / period))
}
