//! The discrete equation's starting solution: the structure-preserving doubling algorithm on
//! `(Ā, G, Q)` (no inverse of `A`, so pure delay states with singular `A` are fine). It stops
//! when its change falls to rounding or stops falling; Newton's refinement finishes the job.
//! Doubling converges to the smallest positive semi-definite solution, which is the stabilising
//! one only when every unstable mode is seen by the penalty: the caller starts from a
//! regularised penalty when it is not.

use super::problem::{Problem, Stall};
use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::linalg::lu::partial_pivoting::factor::{lu_in_place, lu_in_place_scratch};
use faer::linalg::lu::partial_pivoting::solve::{solve_in_place, solve_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use nalgebra::DMatrix;

/// Doubling steps at most (each squares the horizon).
const MAX_STEPS: usize = 100;

/// `X` by doubling with penalty `q` (the problem's `Q̄` or a regularised one), or the steps
/// taken when the iteration fails. Each step: `W = I + GₖHₖ` factored once (faer's LU,
/// sequential) and solved for `[Aₖ Gₖ]` together, then `Aₖ₊₁ = AₖW⁻¹Aₖ`,
/// `Gₖ₊₁ = Gₖ + AₖW⁻¹GₖAₖᵀ`, `Hₖ₊₁ = Hₖ + AₖᵀHₖW⁻¹Aₖ`.
pub(super) fn doubling_start(p: &Problem, q: &DMatrix<f64>) -> Result<DMatrix<f64>, usize> {
    let n = p.n();
    let from = |m: &DMatrix<f64>| Mat::<f64>::from_fn(n, n, |i, j| m[(i, j)]);
    let (mut ak, mut gk, mut hk) = (from(&p.a0), from(&p.g), from(q));
    let (mut w, mut t) = (Mat::<f64>::zeros(n, n), Mat::<f64>::zeros(n, n));
    let (mut a_next, mut g_next, mut h_next) = (w.clone(), w.clone(), w.clone());
    // [Aₖ Gₖ], then W⁻¹[Aₖ Gₖ].
    let mut solved = Mat::<f64>::zeros(n, 2 * n);
    let (mut forward, mut backward) = (vec![0usize; n], vec![0usize; n]);
    let mut memory = MemBuffer::new(StackReq::any_of(&[
        lu_in_place_scratch::<usize, f64>(n, n, Par::Seq, Default::default()),
        solve_in_place_scratch::<usize, f64>(n, 2 * n, Par::Seq),
    ]));
    let stack = MemStack::new(&mut memory);
    // `dst = lhs·rhs` or `dst += lhs·rhs`.
    let product = |dst: &mut Mat<f64>, accum: Accum, lhs: MatRef<f64>, rhs: MatRef<f64>| {
        matmul(dst.as_mut(), accum, lhs, rhs, 1.0, Par::Seq);
    };
    // Only far down: a weakly weighted unstable mode grows from a relative 1e-6 of the whole,
    // and stopping then would leave it unstabilised.
    let mut stall = Stall::below(1e-12);
    for step in 1..=MAX_STEPS {
        product(&mut w, Accum::Replace, gk.as_ref(), hk.as_ref());
        for i in 0..n {
            w[(i, i)] += 1.0;
        }
        let (_, perm) = lu_in_place(
            w.as_mut(),
            &mut forward,
            &mut backward,
            Par::Seq,
            stack,
            Default::default(),
        );
        if (0..n).any(|i| !(w[(i, i)] != 0.0 && w[(i, i)].is_finite())) {
            return Err(step);
        }
        solved.as_mut().submatrix_mut(0, 0, n, n).copy_from(&ak);
        solved.as_mut().submatrix_mut(0, n, n, n).copy_from(&gk);
        solve_in_place(
            w.as_ref(),
            w.as_ref(),
            perm,
            solved.as_mut(),
            Par::Seq,
            stack,
        );
        let (w_a, w_g) = solved.as_ref().split_at_col(n);
        product(&mut t, Accum::Replace, hk.as_ref(), w_a);
        h_next.copy_from(&hk);
        product(&mut h_next, Accum::Add, ak.transpose(), t.as_ref());
        product(&mut t, Accum::Replace, ak.as_ref(), w_g);
        g_next.copy_from(&gk);
        product(&mut g_next, Accum::Add, t.as_ref(), ak.transpose());
        product(&mut a_next, Accum::Replace, ak.as_ref(), w_a);
        let (mut change, mut size) = (0.0, 0.0);
        for j in 0..n {
            for i in 0..n {
                let (h, g) = (
                    0.5 * (h_next[(i, j)] + h_next[(j, i)]),
                    0.5 * (g_next[(i, j)] + g_next[(j, i)]),
                );
                change += (h - hk[(i, j)]) * (h - hk[(i, j)]);
                size += h * h;
                (hk[(i, j)], gk[(i, j)]) = (h, g);
            }
        }
        std::mem::swap(&mut ak, &mut a_next);
        let change = (change / size.max(f64::MIN_POSITIVE)).sqrt();
        if !change.is_finite() {
            return Err(step);
        }
        if change <= 1e-15 || stall.stalled(change) {
            return Ok(DMatrix::from_fn(n, n, |i, j| hk[(i, j)]));
        }
    }
    Err(MAX_STEPS)
}
