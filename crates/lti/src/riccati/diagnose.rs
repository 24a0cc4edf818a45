//! Why an equation has no stabilising solution, named from its data: a mode the input cannot
//! move that is not stable (`(A, B)` not stabilisable), a mode on the stability boundary that
//! the penalty does not see, or (continuous, with a penalty that is not semi-definite) a
//! Hamiltonian eigenvalue on the imaginary axis to working precision. With a semi-definite
//! penalty the Hamiltonian's eigenvalues on the axis are exactly the first two kinds
//! ([`resolution`](super::resolution)), so an eigenvalue merely near it is not named as on it.

use super::problem::{Kind, Problem};
use super::{Mode, RiccatiError};
use nalgebra::DMatrix;
use num_complex::Complex64;

/// A rank test's threshold: the smallest singular value with each block at unit norm.
const RANK_TOL: f64 = 1e-10;

/// How close to the stability boundary (relative: `|Re λ| / ‖A‖`, or `||λ| − 1|`) a mode counts
/// as on it.
const BOUNDARY_TOL: f64 = 1e-9;

/// A mode on the stability boundary that the input cannot move or the penalty does not see:
/// checked before solving (cheap: boundary modes are few), since a solver can land a rounding
/// error away from such a mode and look stabilising.
pub(super) fn boundary_modes(p: &Problem) -> Option<RiccatiError> {
    modes(p, true)
}

/// The reason the data show, if they show one.
pub(super) fn diagnose(p: &Problem) -> Option<RiccatiError> {
    modes(p, false).or_else(|| hamiltonian_on_axis(p))
}

/// PBH tests of the modes on the boundary (and, unless `boundary_only`, outside it).
fn modes(p: &Problem, boundary_only: bool) -> Option<RiccatiError> {
    let n = p.n();
    let scale = p.a0.norm().max(f64::MIN_POSITIVE);
    // Each block at unit norm: a rank test must not depend on the blocks' units.
    let complex = |m: &DMatrix<f64>| {
        let size = m.norm().max(f64::MIN_POSITIVE);
        m.map(|v| Complex64::new(v / size, 0.0))
    };
    let (a, b, q) = (complex(&p.a0), complex(&p.b), complex(&p.q0));
    let smallest = |m: DMatrix<Complex64>| {
        m.svd(false, false)
            .singular_values
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min)
    };
    for l in crate::state_space::eigenvalues(&p.a0) {
        let (outside, on) = match p.kind {
            Kind::Continuous => (l.re >= 0.0, l.re.abs() <= BOUNDARY_TOL * scale),
            Kind::Discrete => (l.norm() >= 1.0, (l.norm() - 1.0).abs() <= BOUNDARY_TOL),
        };
        if !(on || (outside && !boundary_only)) {
            continue;
        }
        let shifted = &a - DMatrix::<Complex64>::identity(n, n) * (l / scale);
        let mut ab = DMatrix::zeros(n, n + b.ncols());
        ab.view_mut((0, 0), (n, n)).copy_from(&shifted);
        ab.view_mut((0, n), (n, b.ncols())).copy_from(&b);
        if smallest(ab) <= RANK_TOL {
            return Some(RiccatiError::Unstabilisable { mode: Mode::of(l) });
        }
        let mut aq = DMatrix::zeros(2 * n, n);
        aq.view_mut((0, 0), (n, n)).copy_from(&shifted);
        aq.view_mut((n, 0), (n, n)).copy_from(&q);
        if on && smallest(aq) <= RANK_TOL {
            return Some(RiccatiError::UnseenBoundaryMode { mode: Mode::of(l) });
        }
    }
    None
}

/// An eigenvalue of the Hamiltonian that cannot be told from the imaginary axis, when the
/// penalty is not semi-definite (when it is, only the boundary modes put one there).
fn hamiltonian_on_axis(p: &Problem) -> Option<RiccatiError> {
    (p.kind == Kind::Continuous && !super::resolution::semidefinite_penalty(p))
        .then(|| super::resolution::hamiltonian_on_axis(p))
        .flatten()
        .map(|l| RiccatiError::HamiltonianOnAxis {
            eigenvalue: Mode::of(l),
        })
}
