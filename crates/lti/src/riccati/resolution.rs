//! Whether an eigenvalue near the stability boundary can be told from one on it, and what the
//! data's structure says when it cannot.
//!
//! Continuous: every closed-loop eigenvalue λ is one of the Hamiltonian's, and rounding in the
//! data and in the computation moves a simple eigenvalue by about `κ(λ)·ε·‖H‖` at most (its
//! first-order perturbation bound), with `κ(λ) = ‖x‖‖y‖/|yᴴx|` from its right and left
//! eigenvectors (Wilkinson's condition number, in the balanced basis). One farther than
//! [`BOUNDS`] times that from the axis is resolved: CAREX 14's closed-loop pair 5·10⁻¹³ from
//! the axis has `κ = 1` and is told apart by three orders of magnitude. A double eigenvalue on
//! the axis — where no stabilising solution exists — is computed about `√ε·‖H‖` off it, but
//! its eigenvectors are then nearly orthogonal (`κ ~ 1/√ε`) and its bound covers the distance.
//! Only eigenvalues within that `√ε·‖H‖` pay for the eigenvectors (inverse iteration, O(n³)
//! each).
//!
//! That bound cannot tell a double eigenvalue on the axis from a simple pair `±d` a hair off it
//! (the pair is within about `d²` of a double eigenvalue, at `d ≈ 10⁻⁸` rounding), and nothing
//! else the computation shows does. Measured on CAREX 11 at ε = 0 (a double pair at `±i`, the
//! closed loop exactly on the axis) and on a mode at `±10⁻⁸` that `Q` does not see, hidden by
//! an orthogonal change of basis (n = 6, `tests/data/near_boundary_care.txt`): the
//! Hamiltonian's pair is computed 5·10⁻⁹ from the axis (CAREX 11) and 1.2·10⁻⁸, 2.5·10⁻⁸ (the
//! hidden mode) with bounds of 1.7 … 7.8·10⁻⁷ and 0.8 … 1.1·10⁻⁷; the stable invariant subspace
//! has dimension `n` in each; Newton's method from the regularised start converges linearly with
//! ratio ½ in each (the closed loop's abscissa halving from 10⁻³: the Fréchet derivative
//! `Z ↦ AcᵀZ + ZAc` is singular at the limit, or 2·10⁻⁸ from it), its residual reaching rounding
//! while the closed loop is still 10⁻⁷ from the axis. (The sign function fails to converge on CAREX
//! 11 and converges on these two, but gives no usable start for other hidden modes alike.)
//!
//! The data's structure does tell them apart. With `Q̄ = Q − SR⁻¹Sᵀ ≥ 0` and `G = BR⁻¹Bᵀ ≥ 0`,
//! an eigenpair `H[x; y] = λ[x; y]` has `2·Re λ·yᴴx = −(xᴴQ̄x + yᴴGy)`, so on the axis `Q̄x = 0`
//! and `Gy = 0`: `λ` is then a mode of `Ā` on the axis that `Q̄` does not see (`x`) or the input
//! cannot move (`y`), which the data's boundary modes are checked for directly
//! ([`diagnose::boundary_modes`](super::diagnose::boundary_modes), to a relative 10⁻⁹). When
//! there is none, no perturbation of the data that keeps the penalties semi-definite puts an
//! eigenvalue of the Hamiltonian on the axis, whatever its bound: the solution from the stable
//! invariant subspace is the stabilising one, and is returned with a warning
//! ([`NearBoundary`](super::NearBoundary): the eigenvalue's distance, its first-order bound, the
//! solution's estimated forward error). CAREX 11's `Q` is indefinite (eigenvalues −13.2 and
//! 0.23): nothing but rounding separates its pair from the axis — on the axis, to working
//! precision — and it is refused. `Q̄` counts as semi-definite when its smallest eigenvalue is
//! above `−10·n·ε·(‖Q‖ + ‖S‖²‖R⁻¹‖)`: a penalty formed as `CᵀC` in floating point is, its null
//! directions weighted ±10⁻¹⁶ — which near the axis can matter: for about a quarter of hidden
//! modes at ±10⁻⁸ (random bases), the stored data's rounding weighs the mode negatively and their
//! exact Hamiltonian has its pair on the axis. The solution returned is then that of the
//! semi-definite data within rounding of them, which the warning's bound covers.
//!
//! Discrete: the same with the symplectic pencil `L − λM`, `L = [Ā 0; −Q̄ I]`,
//! `M = [I G; 0 Āᵀ]` (the costate scaled so that `Q̄` and `G` weigh alike), whose finite
//! eigenvalues include the closed loop's: the bound `κ·ε·(‖L‖ + |λ|·‖M‖)` with
//! `κ = ‖x‖‖y‖/|yᴴMx|`, suspects within `√ε·(‖L‖ + ‖M‖)` of the unit circle, and the same
//! structure (with `Q̄ ≥ 0` the pencil's eigenvalues on the circle are boundary modes of `A`
//! unseen or unmoved). DAREX 14's lag pole 1 − 2.2·10⁻⁸ (τ = 10⁸: seen, and moved by an input of
//! 10⁻⁸) is resolved — scaled against `G`, a simple eigenvalue; the hidden mode above in
//! discrete form (`I + A/2`: at 1 ± 5·10⁻⁹) is not, and is returned with the warning.

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
    /// Its first-order perturbation bound: how far rounding can move it.
    pub bound: f64,
    /// How close to the boundary it could lie ([`BOUNDS`] times its bound).
    pub resolution: f64,
}

/// How many rounding errors (times `n`, relative to `‖Q‖ + ‖S‖²‖R⁻¹‖`) `Q̄`'s smallest
/// eigenvalue may lie below zero for `Q̄` to count as semi-definite.
const SEMIDEFINITE_ROUNDING: f64 = 10.0;

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
        let bound = condition(&self.h, None, l) * f64::EPSILON * self.size;
        let resolution = BOUNDS * bound;
        (l.re.abs() <= resolution).then_some(Unresolved {
            eigenvalue: l,
            bound,
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

/// The symplectic pencil `L − λM`, `L = [Ā 0; −Q̄ I]`, `M = [I G; 0 Āᵀ]` (in the balanced
/// state basis), whose finite eigenvalues include the discrete closed loop's, and the sum of
/// their Frobenius norms.
struct Pencil {
    l: DMatrix<f64>,
    m: DMatrix<f64>,
    size: f64,
}

impl Pencil {
    fn of(p: &Problem) -> Self {
        let n = p.n();
        // The costate scaled by `s` (`L → diag(I, I/s)·L·diag(I, sI)`, `M` alike: the
        // eigenvalues stay) so that `Q̄/s` and `sG` weigh alike.
        let (q, g) = (p.q0.norm(), p.g.norm());
        let s = if q > 0.0 && g > 0.0 {
            (q / g).sqrt()
        } else {
            1.0
        };
        let mut l = DMatrix::zeros(2 * n, 2 * n);
        l.view_mut((0, 0), (n, n)).copy_from(&p.a0);
        l.view_mut((n, 0), (n, n)).copy_from(&(&p.q0 * (-1.0 / s)));
        l.view_mut((n, n), (n, n)).fill_with_identity();
        let mut m = DMatrix::zeros(2 * n, 2 * n);
        m.view_mut((0, 0), (n, n)).fill_with_identity();
        m.view_mut((0, n), (n, n)).copy_from(&(&p.g * s));
        m.view_mut((n, n), (n, n)).copy_from(&p.a0.transpose());
        let size = l.norm() + m.norm();
        Pencil { l, m, size }
    }

    /// `l`'s distance from the unit circle is within [`BOUNDS`] of its perturbation bounds
    /// (`κ·ε·(‖L‖ + |λ|·‖M‖)`).
    fn unresolved(&self, l: Complex64) -> Option<Unresolved> {
        let bound = condition(&self.l, Some(&self.m), l)
            * f64::EPSILON
            * (self.l.norm() + l.norm() * self.m.norm());
        let resolution = BOUNDS * bound;
        ((1.0 - l.norm()).abs() <= resolution).then_some(Unresolved {
            eigenvalue: l,
            bound,
            resolution,
        })
    }

    /// Of `eigenvalues`, the one nearest the circle that cannot be told from it, if any; only
    /// those within `√ε·(‖L‖ + ‖M‖)` of it pay for their condition.
    fn nearest_unresolved(&self, eigenvalues: Vec<Complex64>) -> Option<Unresolved> {
        let mut suspects: Vec<Complex64> = eigenvalues
            .into_iter()
            .filter(|l| (1.0 - l.norm()).abs() <= f64::EPSILON.sqrt() * self.size)
            .collect();
        suspects.sort_by(|x, y| (1.0 - x.norm()).abs().total_cmp(&(1.0 - y.norm()).abs()));
        suspects.into_iter().find_map(|l| self.unresolved(l))
    }
}

/// The closed-loop eigenvalue (of `eigenvalues`) nearest the boundary that cannot be told from
/// it, if any.
pub(super) fn closed_loop(p: &Problem, eigenvalues: Vec<Complex64>) -> Option<Unresolved> {
    match p.kind {
        Kind::Continuous => Hamiltonian::of(p).nearest_unresolved(eigenvalues),
        Kind::Discrete => Pencil::of(p).nearest_unresolved(eigenvalues),
    }
}

/// Whether every eigenvalue of `eigenvalues` on or outside the boundary is within its resolution
/// of it (a closed loop computed unstable only by what rounding can do to it).
pub(super) fn instability_unresolved(p: &Problem, eigenvalues: &[Complex64]) -> bool {
    match p.kind {
        Kind::Continuous => {
            let h = Hamiltonian::of(p);
            eigenvalues
                .iter()
                .filter(|l| l.re >= 0.0)
                .all(|&l| h.unresolved(l).is_some())
        }
        Kind::Discrete => {
            let pencil = Pencil::of(p);
            eigenvalues
                .iter()
                .filter(|l| l.norm() >= 1.0)
                .all(|&l| pencil.unresolved(l).is_some())
        }
    }
}

/// Whether `Q̄` is positive semi-definite to rounding (`G` is, `R` being positive definite): then
/// the Hamiltonian's (or symplectic pencil's) eigenvalues on the boundary are exactly the
/// boundary modes of `Ā` that `Q̄` does not see or the input cannot move.
pub(super) fn semidefinite_penalty(p: &Problem) -> bool {
    let n = p.n();
    if n == 0 {
        return true;
    }
    // `Q̄ = Q − SR⁻¹Sᵀ` is rounded relative to its terms' factors.
    let r_inverse = p.r.clone().cholesky().map_or(0.0, |c| c.inverse().norm());
    let scale = p.q.norm() + p.s.norm_squared() * r_inverse;
    let smallest = p.q0.clone().symmetric_eigenvalues().min();
    smallest >= -SEMIDEFINITE_ROUNDING * n as f64 * f64::EPSILON * scale
}

/// An eigenvalue of the continuous equation's Hamiltonian that cannot be told from the
/// imaginary axis (the nearest), if any.
pub(super) fn hamiltonian_on_axis(p: &Problem) -> Option<Complex64> {
    let h = Hamiltonian::of(p);
    h.nearest_unresolved(crate::state_space::eigenvalues(&h.h))
        .map(|u| u.eigenvalue)
}

/// The condition number `‖x‖‖y‖/|yᴴMx|` of the eigenvalue `l` of the pencil `L − λM` (`M = I`
/// when `None`: Wilkinson's for a matrix), its eigenvectors by inverse iteration on `L − lM`
/// (infinite when they cannot be found).
fn condition(lm: &DMatrix<f64>, mm: Option<&DMatrix<f64>>, l: Complex64) -> f64 {
    let n = lm.nrows();
    let complex = |m: &DMatrix<f64>| m.map(|v| Complex64::new(v, 0.0));
    let mass = mm.map_or_else(|| DMatrix::<Complex64>::identity(n, n), complex);
    let size = lm.norm() + mm.map_or(0.0, |m| m.norm());
    // A hair off `l`, so that the factorisation of a computed eigenvalue is never exactly
    // singular (the eigenvectors do not see it).
    let shift = l + Complex64::new(f64::EPSILON, f64::EPSILON) * size;
    let shifted = complex(lm) - &mass * shift;
    let right = shifted.clone().lu();
    let left = shifted.adjoint().lu();
    let start = DVector::from_fn(n, |k, _| {
        Complex64::new(
            1.0 + 0.5 * ((k * 7) % 5) as f64,
            0.25 * ((k * 3) % 4) as f64,
        )
    });
    let iterate = |lu: &nalgebra::LU<Complex64, nalgebra::Dyn, nalgebra::Dyn>,
                   mass: &DMatrix<Complex64>| {
        let mut v = start.normalize();
        for _ in 0..INVERSE_STEPS {
            v = lu.solve(&(mass * &v))?;
            let size = v.norm();
            if !(size.is_finite() && size > 0.0) {
                return None;
            }
            v /= Complex64::new(size, 0.0);
        }
        Some(v)
    };
    match (iterate(&right, &mass), iterate(&left, &mass.adjoint())) {
        (Some(x), Some(y)) => 1.0 / y.dotc(&(&mass * x)).norm(),
        _ => f64::INFINITY,
    }
}
