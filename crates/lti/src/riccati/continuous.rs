//! The continuous equation's starting solution: the matrix sign function of the Hamiltonian
//! `H = [Ā −G; −Q −Āᵀ]` by Newton's iteration with determinant scaling, then Byers' formula for
//! `X`. The iteration stops when its change falls to rounding or stops falling (stagnation: on
//! large problems the change stalls near 1e-12, with Hamiltonian eigenvalues near the axis near
//! 1e-6, and would otherwise spin to the step limit); Newton's method on the Riccati equation
//! finishes the job.

use super::problem::{Problem, Stall};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::lu::partial_pivoting::inverse::{inverse, inverse_scratch};
use faer::{Mat, Par};
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

/// The matrix sign function by scaled Newton iteration, with the steps taken: each step one
/// LU factorisation (faer, sequential) gives the inverse and the determinant's scaling.
fn sign(h: &DMatrix<f64>) -> Result<(DMatrix<f64>, usize), usize> {
    let n = h.nrows();
    let mut z = Mat::<f64>::from_fn(n, n, |i, j| h[(i, j)]);
    let mut lu = Mat::<f64>::zeros(n, n);
    let mut inv = Mat::<f64>::zeros(n, n);
    let (mut forward, mut backward) = (vec![0usize; n], vec![0usize; n]);
    let mut memory = MemBuffer::new(StackReq::any_of(&[
        lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default()),
        inverse_scratch::<usize, f64>(n, Par::Seq),
    ]));
    let stack = MemStack::new(&mut memory);
    // Near-axis eigenvalues stall it as high as 1e-5.
    let mut stall = Stall::below(1e-3);
    for step in 1..=MAX_STEPS {
        lu.copy_from(&z);
        let (_, perm) = lu_in_place(
            lu.as_mut(),
            &mut forward,
            &mut backward,
            Par::Seq,
            stack,
            Default::default(),
        );
        // |det|^(−1/n) from the pivots' logarithms (the determinant itself over- or
        // underflows at this size).
        let mut log_det = 0.0;
        for i in 0..n {
            let u = lu[(i, i)].abs();
            if !(u > 0.0 && u.is_finite()) {
                return Err(step);
            }
            log_det += libm::log(u);
        }
        inverse(
            inv.as_mut(),
            lu.as_ref(),
            lu.as_ref(),
            perm,
            Par::Seq,
            stack,
        );
        let c = libm::exp(-log_det / n as f64);
        let c = if c.is_finite() && c > 0.0 { c } else { 1.0 };
        let (mut change, mut size) = (0.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                let next = 0.5 * (z[(i, j)] * c + inv[(i, j)] / c);
                change += (next - z[(i, j)]) * (next - z[(i, j)]);
                size += next * next;
                z[(i, j)] = next;
            }
        }
        let change = (change / size).sqrt();
        if !change.is_finite() {
            return Err(step);
        }
        if change < 1e-14 || stall.stalled(change) {
            return Ok((DMatrix::from_fn(n, n, |i, j| z[(i, j)]), step));
        }
    }
    Err(MAX_STEPS)
}
