//! The frequency response of the path a reference takes through the tick — the zero-phase
//! smoothing, then the feedforward — as the linear maps the tick applies (clamping aside):
//! what an analysis that adds a signal to the reference (repetitive control, a study of the
//! tracking error) multiplies the closed loop's responses by.

use crate::deployment::MAX_PREVIEW;
use crate::deployment::{Deployment, FeedforwardSpec};
use core::f64::consts::TAU;

/// A complex number `[re, im]`.
pub type Complex = [f64; 2];

fn mul(a: Complex, b: Complex) -> Complex {
    [a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]]
}

/// The reference path at one frequency: a desired position `r` of that frequency (m) reaches
/// the feedback as `reference·r` (m) and adds `feedforward_v_per_m·r` (V) to the controller's
/// command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathResponse {
    /// The reference the feedback compares with, per metre desired.
    pub reference: Complex,
    /// The feedforward command in V per metre desired.
    pub feedforward_v_per_m: Complex,
}

/// The reference path of the loop `d` at `f_hz` (Hz), for a reference given `preview` ticks
/// ahead as the tick reads it.
pub fn reference_path(d: &Deployment, f_hz: f64) -> PathResponse {
    let t = d.period_s();
    let w = TAU * f_hz * t;
    let half = d.smoothing_half();
    let weights = hann_weights(half);
    let smoothing = weights[0]
        + 2.0
            * (1..=half)
                .map(|i| weights[i] * libm::cos(w * i as f64))
                .sum::<f64>();
    let z = |ticks: f64| [libm::cos(w * ticks), libm::sin(w * ticks)];
    let scaled = |c: Complex, s: f64| [c[0] * s, c[1] * s];
    match &d.feedforward {
        FeedforwardSpec::None => PathResponse {
            reference: [smoothing, 0.0],
            feedforward_v_per_m: [0.0, 0.0],
        },
        FeedforwardSpec::Model => {
            let s = &d.stage;
            let newton_per_volt = s.current_gain_a_per_v * s.kt_n_per_a;
            // Central differences of the window: (z − z⁻¹)/2T and (z − 2 + z⁻¹)/T².
            let accel = (2.0 * libm::cos(w) - 2.0) / (t * t);
            let velocity = libm::sin(w) / t;
            let v = [
                (s.suspended_mass_kg * accel + s.stiffness_n_per_m) / newton_per_volt,
                s.damping_n_s_per_m * velocity / newton_per_volt,
            ];
            PathResponse {
                reference: [smoothing, 0.0],
                feedforward_v_per_m: scaled(v, smoothing),
            }
        }
        FeedforwardSpec::Zpetc(spec) => {
            let zi = z(-1.0);
            let zi2 = z(-2.0);
            let mut filter = z(spec.preview as f64);
            for &[b0, b1, b2, a1, a2] in &spec.sections[..spec.sections_used] {
                let num = [b0 + b1 * zi[0] + b2 * zi2[0], b1 * zi[1] + b2 * zi2[1]];
                let den = [1.0 + a1 * zi[0] + a2 * zi2[0], a1 * zi[1] + a2 * zi2[1]];
                let d2 = den[0] * den[0] + den[1] * den[1];
                let ratio = mul(num, [den[0] / d2, -den[1] / d2]);
                filter = mul(filter, ratio);
            }
            PathResponse {
                reference: scaled(filter, spec.gain * smoothing),
                feedforward_v_per_m: [0.0, 0.0],
            }
        }
        FeedforwardSpec::Fir(spec) => {
            let mut filter = [0.0, 0.0];
            for (i, &h) in spec.taps[..spec.taps_used].iter().enumerate() {
                let zi = z(spec.preview as f64 - (i * spec.stride) as f64);
                filter = [filter[0] + h * zi[0], filter[1] + h * zi[1]];
            }
            PathResponse {
                reference: scaled(filter, smoothing),
                feedforward_v_per_m: [0.0, 0.0],
            }
        }
    }
}

/// Normalised Hann weights `w[|i|]` over `2·half + 1` taps (endpoints, zero, excluded):
/// `w[0] + 2·Σ w[i] = 1`. `half` ≤ [`MAX_PREVIEW`].
pub fn hann_weights(half: usize) -> [f64; MAX_PREVIEW + 1] {
    let mut weights = [0.0; MAX_PREVIEW + 1];
    let n = (2 * half + 2) as f64;
    for (i, w) in weights.iter_mut().enumerate().take(half + 1) {
        *w = 0.5 + 0.5 * libm::cos(core::f64::consts::TAU * i as f64 / n);
    }
    let sum = weights[0] + 2.0 * weights[1..=half].iter().sum::<f64>();
    weights.iter_mut().for_each(|w| *w /= sum);
    weights
}
