//! The square root of a covariance: what turns unit normal draws into a process's noise
//! (the simulated stage's exact noise steps) and what balanced truncation factors its gramians
//! with.

use nalgebra::DMatrix;

/// A square root `R` with `P = Rᵀ R` of a symmetric positive semi-definite matrix, through
/// its eigen-decomposition (`R = Λ^½ Vᵀ`; eigenvalues below zero by rounding count as zero, so
/// it is robust to the near-singular gramians of lightly coupled states).
pub fn sqrt_factor(p: &DMatrix<f64>) -> DMatrix<f64> {
    let sym = (p + p.transpose()) * 0.5;
    let e = sym.symmetric_eigen();
    let d = DMatrix::from_diagonal(&e.eigenvalues.map(|l| l.max(0.0).sqrt()));
    d * e.eigenvectors.transpose()
}
