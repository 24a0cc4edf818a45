//! The continuous equation's starting solution: the matrix sign function of the Hamiltonian
//! `H = [Ā −G; −Q −Āᵀ]` by Newton's iteration with determinant scaling, then Byers' formula for
//! `X`. The iteration stops when its change falls to rounding or stops falling (stagnation: on
//! large problems the change stalls near 1e-12, with Hamiltonian eigenvalues near the axis near
//! 1e-6, and would otherwise spin to the step limit); Newton's method on the Riccati equation
//! finishes the job.

use super::problem::{Problem, Stall};
use nalgebra::DMatrix;

/// Sign-function steps at most.
const MAX_STEPS: usize = 100;

/// `X` from the sign of the Hamiltonian with penalty `q` (the problem's `Q̄` or a regularised
/// one), or the steps taken when the iteration fails.
pub(super) fn sign_start(p: &Problem, q: &DMatrix<f64>) -> Result<DMatrix<f64>, usize> {
    let n = p.n();
    let mut h = p.hamiltonian();
    h.view_mut((n, 0), (n, n)).copy_from(&(-q));
    let (z, steps) = sign(&h)?;
    let id = DMatrix::<f64>::identity(n, n);
    // [Z12; Z22 + I] X = −[Z11 + I; Z21]  (least squares; Byers 1987)
    let mut lhs = DMatrix::zeros(2 * n, n);
    lhs.view_mut((0, 0), (n, n))
        .copy_from(&z.view((0, n), (n, n)));
    lhs.view_mut((n, 0), (n, n))
        .copy_from(&(z.view((n, n), (n, n)) + &id));
    let mut rhs = DMatrix::zeros(2 * n, n);
    rhs.view_mut((0, 0), (n, n))
        .copy_from(&(-(z.view((0, 0), (n, n)) + &id)));
    rhs.view_mut((n, 0), (n, n))
        .copy_from(&(-z.view((n, 0), (n, n))));
    // Singular values below rounding relative to the largest count as zero (an absolute
    // threshold would zero a well-posed but small-scaled problem's).
    let svd = lhs.svd(true, true);
    let largest = svd.singular_values.max();
    svd.solve(&rhs, largest * (2 * n) as f64 * f64::EPSILON)
        .map_err(|_| steps)
}

/// The matrix sign function by scaled Newton iteration, with the steps taken.
fn sign(h: &DMatrix<f64>) -> Result<(DMatrix<f64>, usize), usize> {
    let n = h.nrows();
    let mut z = h.clone();
    // Near-axis eigenvalues stall it as high as 1e-5.
    let mut stall = Stall::below(1e-3);
    for step in 1..=MAX_STEPS {
        let inv = z.clone().try_inverse().ok_or(step)?;
        let det = z.determinant().abs();
        let c = if det > 0.0 && det.is_finite() {
            libm::pow(det, -1.0 / n as f64)
        } else {
            1.0
        };
        let next = (&z * c + inv / c) * 0.5;
        let change = (&next - &z).norm() / next.norm();
        z = next;
        if !change.is_finite() {
            return Err(step);
        }
        if change < 1e-14 || stall.stalled(change) {
            return Ok((z, step));
        }
    }
    Err(MAX_STEPS)
}
