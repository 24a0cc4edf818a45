//! The discrete equation's starting solution: the structure-preserving doubling algorithm on
//! `(Ā, G, Q)` (no inverse of `A`, so pure delay states with singular `A` are fine). It stops
//! when its change falls to rounding or stops falling; Newton's refinement finishes the job.
//! Doubling converges to the smallest positive semi-definite solution, which is the stabilising
//! one only when every unstable mode is seen by the penalty: the caller starts from a
//! regularised penalty when it is not.

use super::problem::{symmetric, Problem, Stall};
use nalgebra::DMatrix;

/// Doubling steps at most (each squares the horizon).
const MAX_STEPS: usize = 100;

/// `X` by doubling with penalty `q` (the problem's `Q̄` or a regularised one), or the steps
/// taken when the iteration fails.
pub(super) fn doubling_start(p: &Problem, q: &DMatrix<f64>) -> Result<DMatrix<f64>, usize> {
    let id = DMatrix::<f64>::identity(p.n(), p.n());
    let (mut ak, mut gk, mut hk) = (p.a0.clone(), p.g.clone(), q.clone());
    // Only far down: a weakly weighted unstable mode grows from a relative 1e-6 of the whole,
    // and stopping then would leave it unstabilised.
    let mut stall = Stall::below(1e-12);
    for step in 1..=MAX_STEPS {
        let w = (&id + &gk * &hk).lu();
        let w_a = w.solve(&ak).ok_or(step)?;
        let w_g = w.solve(&gk).ok_or(step)?;
        let h_next = &hk + ak.transpose() * &hk * &w_a;
        let g_next = &gk + &ak * &w_g * ak.transpose();
        let a_next = &ak * &w_a;
        let change = (&h_next - &hk).norm() / h_next.norm().max(f64::MIN_POSITIVE);
        (ak, gk, hk) = (a_next, symmetric(g_next), symmetric(h_next));
        if !hk.iter().all(|v| v.is_finite()) {
            return Err(step);
        }
        if change <= 1e-15 || stall.stalled(change) {
            return Ok(hk);
        }
    }
    Err(MAX_STEPS)
}
