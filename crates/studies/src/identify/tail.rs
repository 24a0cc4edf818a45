//! A mode above the measured band, seen only by its tail: a resonance past the top frequency
//! (a sensor mount at 5–9 kHz under a 5 kHz measurement, say) bends the band's top — a phase
//! lead or lag growing as `f/(f₀² − f²)`, a magnitude change as `f²` — and a four-mass fit
//! without it leans its high-frequency parameters (m4, k4, c4) toward that bend on every
//! stage alike. Fitted as a pole and zero pair above the band, kept only when it removes more
//! of the residual than noise fitted by four more parameters would.

use num_complex::Complex64;

use super::resonance::ZETA_RANGE;
use plant_sim::modes::ExtraMode;

/// How far above the top measured frequency the mode may lie (a factor on frequency).
const REACH: f64 = 4.0;
/// The F statistic the mode must reach to be kept: the cost it removes per parameter over the
/// residual's variance per degree of freedom; a threshold at F(4, ∞)'s 99.9 % point (χ²₄ at
/// 99.9 %, 18.47, over 4) — nominal, as without the mode its dampings are not identified.
const KEEP_F: f64 = 4.62;
/// Parameters the mode adds (pole and zero frequency, Hz; their damping ratios).
const PARAMETERS: usize = 4;

/// Start and bounds of the mode above `top_hz`, from the measured-over-model `ratio` at the
/// band's top (`top`: its last points): a lead (positive imaginary part) starts the zeros better
/// damped than the poles, a rising magnitude starts the poles below the zeros.
pub(super) fn start_and_bounds(top_hz: f64, top: &[Complex64]) -> ([f64; 4], [f64; 4], [f64; 4]) {
    let mean = top.iter().sum::<Complex64>() / top.len().max(1) as f64;
    let zeta_p = 0.02;
    let zeta_z = if mean.im >= 0.0 {
        2.0 * zeta_p
    } else {
        0.5 * zeta_p
    };
    let (near, far) = (1.5 * top_hz, 2.0 * top_hz);
    let (pole_hz, zero_hz) = if mean.re >= 1.0 {
        (near, far)
    } else {
        (far, near)
    };
    (
        [pole_hz, zeta_p, zero_hz, zeta_z],
        [top_hz, ZETA_RANGE.0, top_hz, ZETA_RANGE.0],
        [REACH * top_hz, ZETA_RANGE.1, REACH * top_hz, ZETA_RANGE.1],
    )
}

/// Whether fitted mode `m` above `top_hz` stays off its frequency bounds (a mode pinned to
/// the band's top or to the reach stands in for something else).
pub(super) fn off_its_bounds(m: &ExtraMode, top_hz: f64) -> bool {
    let inside = |hz: f64| hz > top_hz * (1.0 + 1e-3) && hz < REACH * top_hz * (1.0 - 1e-3);
    inside(m.hz) && inside(m.zero_hz)
}

/// Whether the mode explains more than noise: with costs `without` and `with` it (the sums of
/// squared relative residuals over the same `points`, the fit with it having `parameters`),
/// the F statistic reaches [`KEEP_F`].
pub(super) fn explains_more_than_noise(
    without: f64,
    with: f64,
    points: usize,
    parameters: usize,
) -> bool {
    let dof = (2 * points).saturating_sub(parameters).max(1) as f64;
    let f = (without - with) / PARAMETERS as f64 / (with / dof);
    f > KEEP_F
}
