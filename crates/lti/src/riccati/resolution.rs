//! Whether an eigenvalue near the stability boundary can be told from one on it.
//!
//! Continuous: every closed-loop eigenvalue λ is one of the Hamiltonian's, and rounding in the
//! data and in the computation moves a simple eigenvalue by about `κ(λ)·ε·‖H‖` at most, with
//! `κ(λ) = ‖x‖‖y‖/|yᴴx|` from its right and left eigenvectors (Wilkinson's condition number, in
//! the balanced basis). One farther than a few times that from the axis is off it: CAREX 14's
//! closed-loop pair 5·10⁻¹³ from the axis has `κ = 1` and is told apart by three orders of
//! magnitude. A double eigenvalue on the axis — where no stabilising solution exists — is
//! computed about `√(ε)·‖H‖` off it, but its eigenvectors are then nearly orthogonal
//! (`κ ~ 1/√ε`) and its bound covers the distance. Only eigenvalues within that `√ε·‖H‖` pay
//! for the eigenvectors (inverse iteration, O(n³) each).
//!
//! Discrete: `100·ε·(1 + ‖Ā‖)`, rounding — with `Q ≥ 0` the symplectic pencil's double
//! unit-circle eigenvalues come from boundary modes of `A` that the input cannot move or the
//! penalty does not see, which are checked before solving, while a lag pole a hair inside the
//! circle (DAREX 14: 1 − 10⁻⁸) is a simple eigenvalue, known to rounding.

use super::problem::{Kind, Problem};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// How many first-order perturbation bounds an eigenvalue must lie from the boundary.
const BOUNDS: f64 = 10.0;

/// Inverse-iteration steps for an eigenvector (from a simple eigenvalue computed to rounding,
/// each gains about as many digits as the eigenvalue is separated from the rest).
const INVERSE_STEPS: usize = 3;

/// An eigenvalue that cannot be told from the boundary.
#[derive(Debug, Clone, Copy)]
pub(super) struct Unresolved {
    /// The eigenvalue.
    pub eigenvalue: Complex64,
    /// How close to the boundary it could lie (its perturbation bound, times [`BOUNDS`]).
    pub resolution: f64,
}

/// The balanced Hamiltonian and its Frobenius norm.
struct Hamiltonian {
    h: DMatrix<f64>,
    size: f64,
}

impl Hamiltonian {
    fn of(p: &Problem) -> Self {
        let h = crate::state_space::balance(p.hamiltonian()).0;
        let size = h.norm();
        Hamiltonian { h, size }
    }

    /// Within `√ε·‖H‖` of the axis: where a double eigenvalue on it may be computed.
    fn suspect(&self, l: Complex64) -> bool {
        l.re.abs() <= f64::EPSILON.sqrt() * self.size
    }

    /// `l`'s distance from the axis is within [`BOUNDS`] of its perturbation bounds.
    fn unresolved(&self, l: Complex64) -> Option<Unresolved> {
        let resolution = BOUNDS * condition(&self.h, l) * f64::EPSILON * self.size;
        (l.re.abs() <= resolution).then_some(Unresolved {
            eigenvalue: l,
            resolution,
        })
    }

    /// Of `eigenvalues` (the Hamiltonian's), the one nearest the axis that cannot be told from
    /// it, if any; only the suspects pay for their condition.
    fn nearest_unresolved(&self, eigenvalues: Vec<Complex64>) -> Option<Unresolved> {
        let mut suspects: Vec<Complex64> = eigenvalues
            .into_iter()
            .filter(|&l| self.suspect(l))
            .collect();
        suspects.sort_by(|x, y| x.re.abs().total_cmp(&y.re.abs()));
        suspects.into_iter().find_map(|l| self.unresolved(l))
    }
}

/// The closed-loop eigenvalue (of the stable `eigenvalues`) nearest the boundary that cannot
/// be told from it, if any.
pub(super) fn closed_loop(p: &Problem, eigenvalues: Vec<Complex64>) -> Option<Unresolved> {
    match p.kind {
        Kind::Continuous => Hamiltonian::of(p).nearest_unresolved(eigenvalues),
        Kind::Discrete => {
            let resolution = 100.0 * f64::EPSILON * (1.0 + p.a0.norm());
            eigenvalues
                .into_iter()
                .max_by(|x, y| x.norm().total_cmp(&y.norm()))
                .filter(|l| 1.0 - l.norm() <= resolution)
                .map(|eigenvalue| Unresolved {
                    eigenvalue,
                    resolution,
                })
        }
    }
}

/// An eigenvalue of the continuous equation's Hamiltonian that cannot be told from the
/// imaginary axis (the nearest), if any.
pub(super) fn hamiltonian_on_axis(p: &Problem) -> Option<Complex64> {
    let h = Hamiltonian::of(p);
    h.nearest_unresolved(crate::state_space::eigenvalues(&h.h))
        .map(|u| u.eigenvalue)
}

/// Wilkinson's condition number `‖x‖‖y‖/|yᴴx|` of the eigenvalue `l` of `h`, its eigenvectors
/// by inverse iteration on `h − lI` (infinite when they cannot be found).
fn condition(h: &DMatrix<f64>, l: Complex64) -> f64 {
    let n = h.nrows();
    // A hair off `l`, so that the factorisation of a computed eigenvalue is never exactly
    // singular (the eigenvectors do not see it).
    let shift = l + Complex64::new(f64::EPSILON, f64::EPSILON) * h.norm();
    let m = h.map(|v| Complex64::new(v, 0.0)) - DMatrix::<Complex64>::identity(n, n) * shift;
    let right = m.clone().lu();
    let left = m.adjoint().lu();
    let start = DVector::from_fn(n, |k, _| {
        Complex64::new(
            1.0 + 0.5 * ((k * 7) % 5) as f64,
            0.25 * ((k * 3) % 4) as f64,
        )
    });
    let iterate = |lu: &nalgebra::LU<Complex64, nalgebra::Dyn, nalgebra::Dyn>| {
        let mut v = start.normalize();
        for _ in 0..INVERSE_STEPS {
            v = lu.solve(&v)?;
            let size = v.norm();
            if !(size.is_finite() && size > 0.0) {
                return None;
            }
            v /= Complex64::new(size, 0.0);
        }
        Some(v)
    };
    match (iterate(&right), iterate(&left)) {
        (Some(x), Some(y)) => 1.0 / y.dotc(&x).norm(),
        _ => f64::INFINITY,
    }
}
