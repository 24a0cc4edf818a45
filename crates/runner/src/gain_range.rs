//! The output scales a running loop tolerates (`servo ctl gain`): the sampled closed loop with
//! the controller's output multiplied by k is stable for k strictly between two limits (the
//! loop is conditionally stable: too little gain lets the suspension resonance go unstable, too
//! much the high-frequency crossover). A change is allowed only if it leaves [`MARGIN`] of gain
//! margin on each side.

use crate::closed_loop::ClosedLoop;
use crate::controller::LinearController;
use crate::error::RunError;
use crate::plan::{linear_tick_of, Plan};

/// The gain margin every accepted change keeps, as a factor (2 = 6 dB).
pub const MARGIN: f64 = 2.0;

/// Where the loop goes unstable as its output is scaled, and what a change may set.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainRange {
    /// The loop is unstable at or below this scale (0: stable down to no control).
    pub unstable_below: f64,
    /// The loop is unstable at or above this scale (∞: not within 1000×).
    pub unstable_above: f64,
}

impl GainRange {
    /// The lowest scale a change may set: [`MARGIN`] above the lower limit.
    pub fn low(&self) -> f64 {
        self.unstable_below * MARGIN
    }

    /// The highest scale a change may set: [`MARGIN`] below the upper limit.
    pub fn high(&self) -> f64 {
        self.unstable_above / MARGIN
    }

    /// Whether a change to `scale` is allowed (finite, within [`GainRange::low`]..=[`GainRange::high`]).
    pub fn allows(&self, scale: f64) -> bool {
        scale.is_finite() && scale >= self.low() && scale <= self.high()
    }
}

/// The gain range of `plan`'s loop, by bisection on the spectral radius of the sampled closed
/// loop with the controller's output scaled (to 1e-6 relative); [`RunError::Unstable`] when
/// the loop is not stable as it is.
pub fn gain_range(plan: &Plan) -> Result<GainRange, RunError> {
    plan.check_stable()?;
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
        cl.spectral_radius() < 1.0
    };
    Ok(GainRange {
        unstable_below: limit(&stable, 0.5, 1e-3).unwrap_or(0.0),
        unstable_above: limit(&stable, 2.0, 1e3).unwrap_or(f64::INFINITY),
    })
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
