//! The discrete Lyapunov equation.

use crate::state_space::LtiError;
use nalgebra::DMatrix;

/// Discrete Lyapunov equation `P = A P Aᵀ + Q` for a stable `A`, by Smith's doubling
/// (`P = Σ A^k Q A^kᵀ`, squaring `A` each step): returns `P` and the relative residual
/// `‖A P Aᵀ + Q − P‖ / ‖P‖`. Converges for spectral radius < 1 (slow poles just take more
/// doublings: 64 reach ρ^(2^64)).
pub fn dlyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<(DMatrix<f64>, f64), LtiError> {
    let mut p = q.clone();
    let mut ak = a.clone();
    for _ in 0..64 {
        let next = &p + &ak * &p * ak.transpose();
        let change = (&next - &p).norm();
        p = next;
        ak = &ak * &ak;
        if !(change.is_finite() && p.norm().is_finite() && ak.norm().is_finite()) {
            return Err(LtiError::Argument(
                "dlyap: A is not stable (the series diverges)",
            ));
        }
        if change <= 1e-16 * p.norm() {
            break;
        }
    }
    let residual = (a * &p * a.transpose() + q - &p).norm() / p.norm().max(f64::MIN_POSITIVE);
    if residual.is_nan() || residual > 1e-8 {
        return Err(LtiError::Argument("dlyap: no convergence (A not stable)"));
    }
    Ok((p, residual))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Scalar `p = a² p + q` → `q/(1 − a²)`; and a 2×2 case against the vectorised solution.
    #[test]
    fn dlyap_closed_forms() {
        let (p, r) = dlyap(
            &DMatrix::from_element(1, 1, 0.9),
            &DMatrix::from_element(1, 1, 2.0),
        )
        .unwrap();
        assert!((p[(0, 0)] - 2.0 / (1.0 - 0.81)).abs() < 1e-12 && r < 1e-14);
        // A slow pole (0.1 Hz at 199.6 kHz) still converges.
        let a = libm::exp(-2.0 * PI * 0.1 / 199_600.0f64);
        let (p, _) = dlyap(
            &DMatrix::from_element(1, 1, a),
            &DMatrix::from_element(1, 1, 1.0),
        )
        .unwrap();
        assert!((p[(0, 0)] * (1.0 - a * a) - 1.0).abs() < 1e-9);
        let a2 = DMatrix::from_row_slice(2, 2, &[0.5, 0.3, -0.2, 0.7]);
        let q = DMatrix::from_row_slice(2, 2, &[1.0, 0.2, 0.2, 0.5]);
        let (p, r) = dlyap(&a2, &q).unwrap();
        assert!(r < 1e-13, "{r}");
        // (I − A⊗A) vec(P) = vec(Q)
        let kron = DMatrix::from_fn(4, 4, |i, j| a2[(i / 2, j / 2)] * a2[(i % 2, j % 2)]);
        let vp = (DMatrix::identity(4, 4) - kron)
            .lu()
            .solve(&DMatrix::from_iterator(4, 1, q.transpose().iter().copied()))
            .unwrap();
        for i in 0..2 {
            for j in 0..2 {
                assert!((p[(i, j)] - vp[(i * 2 + j, 0)]).abs() < 1e-12);
            }
        }
        assert!(dlyap(
            &DMatrix::from_element(1, 1, 1.1),
            &DMatrix::from_element(1, 1, 1.0)
        )
        .is_err());
    }
}
