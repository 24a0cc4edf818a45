//! How many digits of a Riccati solution to believe: the relative condition number of the
//! equation (Byers 1985, Kenney & Hewer 1990 for the continuous equation; Sun 1998 for the
//! discrete one; what SLICOT's SB02QD / SB02SD estimate).
//!
//! To first order a perturbation of the data moves the solution by
//! `ΔX = Ω⁻¹(ΔQ + ΔAᵀP + PᵀΔA − NᵀΔG N)` with `Ac` the closed loop and
//! - continuous: `Ω(Z) = AcᵀZ + ZAc` (negated), `P = N = X`;
//! - discrete: `Ω(Z) = Z − AcᵀZAc`, `P = N = X·Ac`.
//!
//! With `Θ(Z) = Ω⁻¹(ZᵀP + PᵀZ)` and `Π(Z) = Ω⁻¹(NᵀZN)` the relative condition number is
//! `κ = (‖Ω⁻¹‖·‖Q‖ + ‖Θ‖·‖A‖ + ‖Π‖·‖G‖) / ‖X‖`: data known to a relative `δ` gives `X` to
//! about `κ·δ`. Each operator norm is estimated by a few power iterations on `L*L`, each a
//! pair of Lyapunov/Stein solves on the closed loop's Schur form (a lower bound that is
//! typically within a few percent).

use super::problem::{Kind, Measured, Problem};
use crate::schur_lyapunov::Side;
use nalgebra::DMatrix;

/// Power iterations per operator norm.
const POWER_STEPS: usize = 3;

/// How far to trust a computed solution (in the balanced state basis of
/// [`RESIDUAL_BOUND`](super::RESIDUAL_BOUND)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensitivity {
    /// The relative condition number `κ`.
    pub condition: f64,
    /// The estimated relative forward error: the residual (at least its rounding, `ε` times the
    /// terms) mapped through `Ω⁻¹` — the Newton correction it implies — plus `κ·ε` for the data
    /// themselves (`(‖Ω⁻¹‖·max(‖Res‖, ε·Σ‖term‖) + κ·ε·‖X‖) / ‖X‖`, SB02QD's FERR in spirit).
    pub forward_error: f64,
}

/// `κ` and the forward error of the solution `m` (infinite when the closed loop's Schur form
/// cannot be computed).
pub(super) fn sensitivity(p: &Problem, m: &Measured) -> Sensitivity {
    let Some(schur) = m.schur() else {
        return Sensitivity {
            condition: f64::INFINITY,
            forward_error: f64::INFINITY,
        };
    };
    let x = &m.x;
    let pn = match p.kind {
        Kind::Continuous => x.clone(),
        Kind::Discrete => x * &m.closed,
    };
    // Ω⁻¹ (up to a sign, which no norm sees) and its adjoint.
    let inverse = |w: &DMatrix<f64>, side: Side| match p.kind {
        Kind::Continuous => schur.continuous(w, side),
        Kind::Discrete => schur.discrete(w, side),
    };
    let omega = |z: &DMatrix<f64>| inverse(z, Side::Transposed);
    let omega_adj = |y: &DMatrix<f64>| inverse(y, Side::Plain);
    let theta = |z: &DMatrix<f64>| omega(&(z.transpose() * &pn + pn.transpose() * z));
    let theta_adj = |y: &DMatrix<f64>| {
        let w = omega_adj(y);
        &pn * (&w + w.transpose())
    };
    let pi = |z: &DMatrix<f64>| omega(&(pn.transpose() * z * &pn));
    let pi_adj = |y: &DMatrix<f64>| {
        let w = omega_adj(y);
        &pn * w * pn.transpose()
    };
    let n = p.n();
    let sep_inv = operator_norm(n, &omega, &omega_adj);
    let size = x.norm().max(f64::MIN_POSITIVE);
    let condition = (sep_inv * p.q0.norm()
        + operator_norm(n, &theta, &theta_adj) * p.a0.norm()
        + operator_norm(n, &pi, &pi_adj) * p.g.norm())
        / size;
    let residual = m.residual.norm().max(f64::EPSILON * m.terms);
    Sensitivity {
        condition,
        forward_error: sep_inv * residual / size + condition * f64::EPSILON,
    }
}

/// `‖L‖` (induced by the Frobenius norm) by power iteration on `L*L` from a fixed start with
/// varied entries (deterministic: the same problem gives the same estimate).
fn operator_norm(
    n: usize,
    l: &dyn Fn(&DMatrix<f64>) -> DMatrix<f64>,
    adjoint: &dyn Fn(&DMatrix<f64>) -> DMatrix<f64>,
) -> f64 {
    let mut z = DMatrix::from_fn(n, n, |i, j| {
        1.0 + 0.5 * (((i * 7 + j * 13) % 5) as f64 - 2.0) / 2.0
    });
    z /= z.norm();
    let mut estimate = 0.0;
    for _ in 0..POWER_STEPS {
        let y = l(&z);
        let back = adjoint(&y);
        let size = back.norm();
        if !(size.is_finite() && size > 0.0) {
            return if size.is_finite() {
                estimate
            } else {
                f64::INFINITY
            };
        }
        estimate = size.sqrt();
        z = back / size;
    }
    estimate
}
