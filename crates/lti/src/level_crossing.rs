//! Where a sampled single-input single-output response crosses a level, found exactly.
//!
//! The frequencies at which `|G(e^{jθ})| = γ` are the eigenvalues on the imaginary axis of a
//! Hamiltonian matrix (Boyd, Balakrishnan & Kabamba 1989; Bruinsma & Steinbuch 1990) of the
//! system mapped to continuous time by the bilinear map `z = (1 + s)/(1 − s)` (`s = jν` ↔
//! `θ = 2·atan ν`, exact on the unit circle). Each such eigenvalue is a candidate; each is then
//! bracketed by direct evaluations of `|G|` on either side and refined by bisection, so a
//! crossing is reported only where the response itself is seen to cross — however narrow the
//! dip — and to full precision. A frequency grid is searched as well, so a crossing the
//! eigenvalues were too ill-conditioned to show is still bracketed.

use crate::frequency_response::FrequencyResponse;
use crate::state_space::{eigenvalues, LtiError, StateSpace};
use nalgebra::DMatrix;
use std::f64::consts::PI;

/// The first frequency in (0, Nyquist) where `|G|` of the SISO discrete system (period
/// `period_s`) falls from `≥ level` to below it, Hz, found as the module says; None when it
/// never does.
pub fn first_fall_below(
    sys: &StateSpace,
    period_s: f64,
    level: f64,
) -> Result<Option<f64>, LtiError> {
    let nyquist = 0.5 / period_s;
    let response = FrequencyResponse::new(sys);
    let gain =
        |f: f64| -> Result<f64, LtiError> { Ok(response.discrete(f, period_s)?[(0, 0)].norm()) };
    // Candidates: the Hamiltonian's (each probed just above too: the crossing is at it), and
    // a 2 % log grid from 1 mHz, walked in order from the last point seen at or above the level.
    let exact = hamiltonian_frequencies(sys, period_s, level);
    let mut candidates: Vec<(f64, bool)> = exact.iter().map(|&f| (f, true)).collect();
    let mut f = 1e-3;
    while f < nyquist {
        candidates.push((f, false));
        f *= 1.02;
    }
    candidates.retain(|(f, _)| f.is_finite() && *f > 1e-3 && *f < nyquist);
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut above = 1e-3;
    if gain(above)? < level {
        return Ok(None);
    }
    for (c, probe) in candidates {
        if gain(c)? < level {
            return Ok(Some(bisect(&gain, above, c, level)?));
        }
        above = c;
        if probe {
            for step in [1e-10, 1e-8, 1e-6, 1e-4] {
                let next = (c * (1.0 + step)).min(nyquist);
                if gain(next)? < level {
                    return Ok(Some(bisect(&gain, c, next, level)?));
                }
            }
        }
    }
    Ok(None)
}

/// Bisection on a log scale between `lo` (|G| ≥ level) and `hi` (below) to the last bit.
fn bisect(
    gain: &impl Fn(f64) -> Result<f64, LtiError>,
    mut lo: f64,
    mut hi: f64,
    level: f64,
) -> Result<f64, LtiError> {
    for _ in 0..80 {
        let mid = (lo * hi).sqrt();
        if mid <= lo || mid >= hi {
            break;
        }
        if gain(mid)? < level {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Ok(hi)
}

/// The frequencies (Hz, in (0, Nyquist)) of the Hamiltonian's eigenvalues near the imaginary
/// axis: where `|G| = level` up to the eigenvalues' accuracy (empty when the map or the
/// eigenvalues fail; the grid then carries the search).
fn hamiltonian_frequencies(sys: &StateSpace, period_s: f64, level: f64) -> Vec<f64> {
    let Some(c) = bilinear_to_continuous(sys) else {
        return Vec::new();
    };
    let (a, b, cm, d) = (&c.a, &c.b, &c.c, c.d[(0, 0)]);
    let r = d * d - level * level;
    if r == 0.0 || !r.is_finite() {
        return Vec::new();
    }
    let n = a.nrows();
    let mut h = DMatrix::zeros(2 * n, 2 * n);
    h.view_mut((0, 0), (n, n))
        .copy_from(&(a - b * cm * (d / r)));
    h.view_mut((0, n), (n, n))
        .copy_from(&(b * b.transpose() * (-level / r)));
    h.view_mut((n, 0), (n, n))
        .copy_from(&(cm.transpose() * cm * (level / r)));
    h.view_mut((n, n), (n, n))
        .copy_from(&(-a.transpose() + cm.transpose() * b.transpose() * (d / r)));
    eigenvalues(&h)
        .into_iter()
        .filter(|z| z.im > 0.0 && z.re.abs() <= 1e-6 * z.norm().max(1.0))
        .map(|z| 2.0 * libm::atan(z.im) / (2.0 * PI * period_s))
        .collect()
}

/// The continuous system with the same response on the imaginary axis as `sys` on the unit
/// circle, under `z = (1 + s)/(1 − s)`: `A_c = (A + I)⁻¹(A − I)`, `B_c = √2 (A + I)⁻¹B`,
/// `C_c = √2 C(A + I)⁻¹`, `D_c = D − C(A + I)⁻¹B`; None when `A` has an eigenvalue at −1.
fn bilinear_to_continuous(sys: &StateSpace) -> Option<StateSpace> {
    let sys = sys.clone().balanced();
    let n = sys.nx();
    let plus = &sys.a + DMatrix::identity(n, n);
    let lu = plus.lu();
    let inv_b = lu.solve(&sys.b)?;
    let inv_a = lu.solve(&(&sys.a - DMatrix::identity(n, n)))?;
    let c_inv = lu.try_inverse().map(|inv| &sys.c * inv)?;
    let root2 = std::f64::consts::SQRT_2;
    Some(StateSpace {
        a: inv_a,
        b: inv_b.clone() * root2,
        c: &c_inv * root2,
        d: &sys.d - &sys.c * inv_b,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;

    /// The bilinear map keeps the response: G_c(jν) = G_d(e^{jθ}), ν = tan(θ/2).
    #[test]
    fn the_bilinear_map_keeps_the_response() {
        let d = StateSpace::from_tf(&[0.2, 0.1, -0.05], &[1.0, -1.2, 0.5]).unwrap();
        let c = bilinear_to_continuous(&d).unwrap();
        for theta in [0.1, 1.0, 2.5] {
            let gd = d.freq_response_discrete(theta / (2.0 * PI), 1.0).unwrap()[(0, 0)];
            let gc: Complex64 = c.freq_response(libm::tan(theta / 2.0)).unwrap()[(0, 0)];
            assert!((gd - gc).norm() < 1e-12, "θ {theta}: {gd} vs {gc}");
        }
    }

    /// A low-pass (falling through −3 dB near 0.1 Hz at 1 Hz sampling) behind a notch at
    /// f₀ ≈ 0.01 Hz whose stretch below −3 dB is 1.6 % wide and lies between two points of a
    /// 2 % grid: the first fall below −3 dB is the notch's, as a dense scan finds it, though
    /// every grid point before the low-pass's own crossing reads above.
    #[test]
    fn a_dip_narrower_than_the_grid_is_the_first_crossing() {
        let f0 = 1e-3 * libm::pow(1.02f64, 116.5);
        let theta = 2.0 * PI * f0;
        let (rz, rp) = (0.99995, 0.9995);
        let notch = StateSpace::from_tf(
            &[1.0, -2.0 * rz * libm::cos(theta), rz * rz],
            &[1.0, -2.0 * rp * libm::cos(theta), rp * rp],
        )
        .unwrap();
        let p = libm::exp(-2.0 * PI * 0.1f64);
        let low = StateSpace::from_tf(&[(1.0 - p) * (1.0 - p)], &[1.0, -2.0 * p, p * p]).unwrap();
        let sys = notch.series(&low).unwrap();
        let gain = |f: f64| sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)].norm();
        let level = gain(1e-3) / 2f64.sqrt();
        // The 2 % grid sees nothing until the low-pass.
        let grid_first = (0..)
            .map(|k| 1e-3 * 1.02f64.powi(k))
            .find(|&f| gain(f) < level)
            .unwrap();
        assert!(grid_first > 0.05, "grid: {grid_first}");
        // A dense scan (steps of 10⁻⁷ of f₀) and the exact search agree.
        let mut dense = f0 * 0.9;
        while gain(dense) >= level {
            dense += f0 * 1e-7;
        }
        let found = first_fall_below(&sys, 1.0, level).unwrap().unwrap();
        assert!((found / dense - 1.0).abs() < 2e-7, "{found} vs {dense}");
        // and the dip is narrower than the grid.
        let mut back = dense;
        while gain(back) < level {
            back += f0 * 1e-6;
        }
        assert!(back / dense - 1.0 < 0.02, "{}", back / dense);
        // A response that never falls that far has no crossing.
        assert_eq!(first_fall_below(&notch, 1.0, 1e-9).unwrap(), None);
    }
}
