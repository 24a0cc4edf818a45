//! What every Riccati benchmark checks: the residual bound, stability, the closed form where
//! the collection gives one, and that the reported forward error covers the actual one.

#![allow(dead_code)] // each test file uses its own part

pub mod extended;
pub mod random;

use lti::riccati::{Riccati, RESIDUAL_BOUND};
use nalgebra::DMatrix;

/// A row-major matrix.
pub fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(r, c, v)
}

/// A diagonal matrix.
pub fn diag(v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_diagonal(&nalgebra::DVector::from_column_slice(v))
}

/// A chain of `n` integrators (continuous) or delays (discrete) driven at its end:
/// `A` the upper shift, `B = eₙ`.
pub fn chain(n: usize) -> (DMatrix<f64>, DMatrix<f64>) {
    let a = DMatrix::from_fn(n, n, |i, j| if j == i + 1 { 1.0 } else { 0.0 });
    let mut b = DMatrix::zeros(n, 1);
    b[(n - 1, 0)] = 1.0;
    (a, b)
}

/// The returned solution keeps its promises: residual within the bound, the estimated
/// forward error positive and finite.
pub fn trusted(name: &str, x: &Riccati) {
    assert!(
        x.residual <= RESIDUAL_BOUND,
        "{name}: residual {:.2e}",
        x.residual
    );
    assert!(
        x.sensitivity().forward_error.is_finite()
            && x.sensitivity().forward_error > 0.0
            && x.sensitivity().condition >= 1.0 - 1e-9,
        "{name}: forward error {:.2e}, condition {:.2e}",
        x.sensitivity().forward_error,
        x.sensitivity().condition
    );
}

/// Relative forward error against a closed form, covered by the solver's own estimate (×10:
/// an estimate, not a bound).
pub fn matches(name: &str, x: &Riccati, want: &DMatrix<f64>) -> f64 {
    trusted(name, x);
    let err = (&x.x - want).norm() / want.norm();
    assert!(
        err <= 10.0 * x.sensitivity().forward_error.max(1e-15),
        "{name}: error {err:.2e} beyond the estimate {:.2e} (κ {:.2e})\n{}\nwant\n{want}",
        x.sensitivity().forward_error,
        x.sensitivity().condition,
        x.x
    );
    err
}
