//! Riccati solvers on benchmark problems in the style of the CAREX and DAREX collections
//! (Benner, Laub & Mehrmann 1995; Abels & Benner 1999): closed-form solutions where they exist,
//! relative residual ≤ 1e-10 everywhere, including ill-conditioned and singular-A cases.

use lti::riccati::{care, dare};
use nalgebra::DMatrix;

fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(r, c, v)
}

fn close(x: &DMatrix<f64>, want: &DMatrix<f64>, tol: f64) {
    let err = (x - want).norm() / want.norm();
    assert!(err < tol, "relative error {err:.2e}\n{x}\nwant\n{want}");
}

/// CAREX 1.1: the double integrator with Q = diag(1, 2): X = [2 1; 1 2].
#[test]
fn carex_double_integrator() {
    let x = care(
        &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
        &m(2, 1, &[0.0, 1.0]),
        &m(2, 2, &[1.0, 0.0, 0.0, 2.0]),
        &m(1, 1, &[1.0]),
        None,
    )
    .unwrap();
    close(&x.x, &m(2, 2, &[2.0, 1.0, 1.0, 2.0]), 1e-12);
    assert!(x.residual < 1e-10);
}

/// CAREX 2.1-type parametric problem, ill-conditioned as ε → 0: A = diag(1, −2), B = [ε; 0],
/// Q = ones, R = 1. Closed form: x₁ = (1 + √(1 + ε²))/ε², x₂ = 1/(1 + ε²x₁),
/// x₃ = (1 − ε²x₂²)/4.
#[test]
fn carex_ill_conditioned_family() {
    for eps in [1.0, 1e-1, 1e-2, 1e-3] {
        let e2: f64 = eps * eps;
        let x1 = (1.0 + (1.0 + e2).sqrt()) / e2;
        let x2 = 1.0 / (1.0 + e2 * x1);
        let x3 = (1.0 - e2 * x2 * x2) / 4.0;
        let x = care(
            &m(2, 2, &[1.0, 0.0, 0.0, -2.0]),
            &m(2, 1, &[eps, 0.0]),
            &m(2, 2, &[1.0, 1.0, 1.0, 1.0]),
            &m(1, 1, &[1.0]),
            None,
        )
        .unwrap();
        close(&x.x, &m(2, 2, &[x1, x2, x2, x3]), 1e-9);
        assert!(x.residual < 1e-10, "ε {eps}: residual {:.2e}", x.residual);
        assert!(x.closed_loop < 0.0);
    }
}

/// A scalable CAREX-style problem: a 1-D heat equation, n = 30 finite differences, input at one
/// end, state penalty: residual check.
#[test]
fn carex_heat_equation_n30() {
    let n = 30;
    let h2 = ((n + 1) * (n + 1)) as f64;
    let a = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
        0 => -2.0 * h2,
        1 => h2,
        _ => 0.0,
    });
    let mut b = DMatrix::zeros(n, 1);
    b[(0, 0)] = h2;
    let q = DMatrix::identity(n, n);
    let x = care(&a, &b, &q, &m(1, 1, &[1.0]), None).unwrap();
    assert!(x.residual < 1e-10, "residual {:.2e}", x.residual);
    assert!(x.closed_loop < 0.0);
}

/// DAREX 1.1-type: A = [4 3; −4.5 −3.5], B = [1; −1], R = 1, Q = [9 6; 6 4]:
/// X = (1 + √5)/2 · Q.
#[test]
fn darex_golden_ratio() {
    let q = m(2, 2, &[9.0, 6.0, 6.0, 4.0]);
    let x = dare(
        &m(2, 2, &[4.0, 3.0, -4.5, -3.5]),
        &m(2, 1, &[1.0, -1.0]),
        &q,
        &m(1, 1, &[1.0]),
        None,
    )
    .unwrap();
    close(&x.x, &(&q * ((1.0 + 5f64.sqrt()) / 2.0)), 1e-10);
    assert!(x.residual < 1e-10);
}

/// Singular A (a pure delay chain, as loop delays give): A = [0 1; 0 0], B = [0; 1],
/// Q = diag(1, 0), R = 1: X = I.
#[test]
fn darex_singular_a_delay_chain() {
    let x = dare(
        &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
        &m(2, 1, &[0.0, 1.0]),
        &m(2, 2, &[1.0, 0.0, 0.0, 0.0]),
        &m(1, 1, &[1.0]),
        None,
    )
    .unwrap();
    close(&x.x, &DMatrix::identity(2, 2), 1e-12);
    assert!(x.residual < 1e-10);
}

/// A longer delay chain behind an unstable mode: A = [[1.2, 1, 0…], shift], n = 12, singular
/// A (the delay states), residual check and stability.
#[test]
fn darex_unstable_mode_behind_a_delay_line() {
    let n = 12;
    let mut a = DMatrix::zeros(n, n);
    a[(0, 0)] = 1.2;
    for i in 0..n - 1 {
        a[(i, i + 1)] = 1.0;
    }
    let mut b = DMatrix::zeros(n, 1);
    b[(n - 1, 0)] = 1.0;
    let mut q = DMatrix::zeros(n, n);
    q[(0, 0)] = 1.0;
    let x = dare(&a, &b, &q, &m(1, 1, &[1e-2]), None).unwrap();
    assert!(x.residual < 1e-10, "residual {:.2e}", x.residual);
    assert!(x.closed_loop < 1.0);
}
