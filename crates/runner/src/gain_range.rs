//! The offline check of a loop (what `servo deploy` writes and a running loop keeps): the
//! sampled closed loop with the controller's output multiplied by k is stable for k strictly
//! between two limits (the loop is conditionally stable: too little gain lets the suspension
//! resonance go unstable, too much the high-frequency crossover). A change is allowed only if
//! it leaves [`servo_config::GAIN_MARGIN`] of gain margin on each side.

use crate::error::RunError;
use crate::plan::{linear_tick_of, Plan};
use loop_model::closed_loop::ClosedLoop;
use loop_model::controller::LinearController;
use loop_model::measured_loop::MeasuredLoop;
use servo_config::{Deployment, Stability};

/// The plan's deployment with its loop checked: its spectral radius and gain range added.
pub fn checked(plan: &Plan) -> Result<Deployment, RunError> {
    Ok(Deployment {
        stability: Some(gain_range(plan)?),
        ..plan.deployment.clone()
    })
}

/// The stability of `plan`'s loop, sealed to it ([`Stability::sealed`]): its spectral radius and
/// its gain range, by bisection on the spectral radius of the sampled closed loop with the
/// controller's output scaled (to 1e-6 relative) and, with a measured FRF, on the loop closed on
/// it over every bin's uncertainty disk ([`loop_model::measured_loop::Verdict`]: the range is
/// the one both allow); [`RunError::Unstable`] when the loop is not stable as it is.
pub fn gain_range(plan: &Plan) -> Result<Stability, RunError> {
    let spectral_radius = plan.check_stable()?;
    let c = &plan.config;
    let tick = linear_tick_of(c, &plan.origin, &plan.sim)?;
    let ctrl = &plan.controller.linear;
    let stable = |k: f64| {
        let scaled = LinearController {
            c: &ctrl.c * k,
            d: &ctrl.d * k,
            ..ctrl.clone()
        };
        let cl = ClosedLoop::new(
            &tick,
            &scaled,
            c.plant.capa.sensitivity_v_per_m,
            plan.period_s(),
        );
        let on_measured = |m: &MeasuredLoop| m.stability.at_scale(k).robustly_stable();
        cl.spectral_radius() < 1.0 && plan.measured.as_ref().is_none_or(on_measured)
    };
    let d = &plan.deployment;
    Ok(Stability {
        spectral_radius,
        unstable_below: limit(&stable, 0.5, 1e-3).unwrap_or(0.0),
        unstable_above: limit(&stable, 2.0, 1e3).unwrap_or(f64::INFINITY),
        sha256: Default::default(),
    }
    .sealed(d.servo_rate_hz, &d.stage, &d.controller))
}

/// From the stable scale 1, steps by `factor` until `stable` fails (or `bound` is passed: None),
/// then bisects (geometrically) to the limit.
fn limit(stable: &impl Fn(f64) -> bool, factor: f64, bound: f64) -> Option<f64> {
    let (mut inside, mut outside) = (1.0, factor);
    while stable(outside) {
        inside = outside;
        outside *= factor;
        if (factor > 1.0 && outside > bound) || (factor < 1.0 && outside < bound) {
            return None;
        }
    }
    while (outside / inside - 1.0).abs() > 1e-6 {
        let mid = (inside * outside).sqrt();
        if stable(mid) {
            inside = mid;
        } else {
            outside = mid;
        }
    }
    Some(outside)
}
