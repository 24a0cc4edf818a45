//! Algebraic Riccati and Lyapunov equations.
//!
//! * DARE `X = AᵀXA − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q` by the structure-preserving
//!   doubling algorithm (SDA: no inverse of `A`, so pure delay states with singular `A` are
//!   fine); cross-checked in the tests against the Riccati difference iteration.
//! * CARE `AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0` by the matrix sign function of the
//!   Hamiltonian (Newton iteration with determinant scaling, Byers' formula for `X`).
//! * Continuous Lyapunov `AX + XAᵀ + Q = 0` by a Cayley transform onto
//!   [`crate::lyapunov::dlyap`].
//!
//! Each returns the solution with its relative residual and the stability of the closed loop,
//! and a typed error when no stabilising solution exists.

use crate::lyapunov::dlyap;
use nalgebra::DMatrix;

/// Why a Riccati or Lyapunov equation has no (stabilising) solution here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RiccatiError {
    /// Matrix shapes do not fit.
    #[error("shape mismatch: {0}")]
    Shape(&'static str),
    /// `R` (or `R + BᵀXB`) is singular or not positive definite.
    #[error("R is not positive definite")]
    SingularR,
    /// The iteration did not converge: typically no stabilising solution (unstabilisable
    /// pair, or eigenvalues of the Hamiltonian/symplectic pencil on the stability boundary).
    #[error("no stabilising solution (iteration did not converge after {iterations} steps)")]
    NoConvergence {
        /// Steps taken.
        iterations: usize,
    },
    /// A solution was found but does not stabilise the closed loop.
    #[error("the solution does not stabilise the loop (closed-loop {measure} = {value})")]
    NotStabilising {
        /// Spectral radius (discrete) or abscissa (continuous).
        measure: &'static str,
        /// Its value.
        value: f64,
    },
}

/// A Riccati solution.
#[derive(Debug, Clone)]
pub struct Riccati {
    /// The stabilising solution X (symmetric).
    pub x: DMatrix<f64>,
    /// The optimal gain `K` with `u = −K x`.
    pub k: DMatrix<f64>,
    /// Relative residual of the equation, ‖·‖_F / ‖X‖_F.
    pub residual: f64,
    /// Closed-loop spectral radius (discrete) or spectral abscissa (continuous) of `A − BK`.
    pub closed_loop: f64,
    /// A condition estimate `‖X‖_F · ‖(R + BᵀXB)⁻¹‖_F` (large = sensitive to data errors).
    pub condition: f64,
}

fn check_shapes(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<(), RiccatiError> {
    let (n, m) = (a.nrows(), b.ncols());
    if a.ncols() != n
        || b.nrows() != n
        || q.shape() != (n, n)
        || r.shape() != (m, m)
        || s.is_some_and(|s| s.shape() != (n, m))
    {
        return Err(RiccatiError::Shape("A n×n, B n×m, Q n×n, R m×m, S n×m"));
    }
    Ok(())
}

fn symmetric(x: DMatrix<f64>) -> DMatrix<f64> {
    (&x + x.transpose()) * 0.5
}

/// Removes the cross term: `Ā = A − B R⁻¹ Sᵀ`, `Q̄ = Q − S R⁻¹ Sᵀ`.
fn without_cross(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r_inv: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> (DMatrix<f64>, DMatrix<f64>) {
    match s {
        Some(s) => (a - b * r_inv * s.transpose(), q - s * r_inv * s.transpose()),
        None => (a.clone(), q.clone()),
    }
}

/// The data both Riccati solvers start from: shapes checked, `R⁻¹`, cross term removed.
struct Prepared {
    n: usize,
    r_inv: DMatrix<f64>,
    a0: DMatrix<f64>,
    q0: DMatrix<f64>,
}

fn prepare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Prepared, RiccatiError> {
    check_shapes(a, b, q, r, s)?;
    let r_inv = r
        .clone()
        .cholesky()
        .ok_or(RiccatiError::SingularR)?
        .inverse();
    let (a0, q0) = without_cross(a, b, q, &r_inv, s);
    Ok(Prepared {
        n: a.nrows(),
        r_inv,
        a0,
        q0,
    })
}

/// Discrete algebraic Riccati equation (optional cross term `S`).
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Riccati, RiccatiError> {
    let Prepared { n, r_inv, a0, q0 } = prepare(a, b, q, r, s)?;
    let id = DMatrix::<f64>::identity(n, n);
    let (mut ak, mut gk, mut hk) = (a0.clone(), b * &r_inv * b.transpose(), q0.clone());
    let mut converged = false;
    let mut steps = 0;
    for _ in 0..100 {
        steps += 1;
        let w = (&id + &gk * &hk).lu();
        let w_a = w
            .solve(&ak)
            .ok_or(RiccatiError::NoConvergence { iterations: steps })?;
        let w_g = w
            .solve(&gk)
            .ok_or(RiccatiError::NoConvergence { iterations: steps })?;
        let h_next = &hk + ak.transpose() * &hk * &w_a;
        let g_next = &gk + &ak * &w_g * ak.transpose();
        let a_next = &ak * &w_a;
        let change = (&h_next - &hk).norm();
        (ak, gk, hk) = (a_next, symmetric(g_next), symmetric(h_next));
        if !hk.iter().all(|v| v.is_finite()) {
            return Err(RiccatiError::NoConvergence { iterations: steps });
        }
        if change <= 1e-15 * hk.norm().max(1e-300) {
            converged = true;
            break;
        }
    }
    if !converged {
        return Err(RiccatiError::NoConvergence { iterations: steps });
    }
    let x = hk;
    let gain_den = r + b.transpose() * &x * b;
    let den_inv = gain_den
        .clone()
        .cholesky()
        .ok_or(RiccatiError::SingularR)?
        .inverse();
    let cross = s.map_or_else(|| DMatrix::zeros(b.ncols(), n), |s| s.transpose());
    let k = &den_inv * (b.transpose() * &x * a + cross);
    let residual_m = a.transpose() * &x * a
        - (a.transpose() * &x * b + s.cloned().unwrap_or_else(|| DMatrix::zeros(n, b.ncols())))
            * &k
        + q
        - &x;
    let residual = residual_m.norm() / x.norm().max(1e-300);
    let closed = a - b * &k;
    let radius = crate::state_space::eigenvalues(&closed)
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max);
    let condition = x.norm() * den_inv.norm();
    solution(
        x,
        k,
        residual,
        condition,
        ("spectral radius", radius, radius < 1.0),
    )
}

/// The result if the closed loop is stable (`measure`, its value, and whether it is).
fn solution(
    x: DMatrix<f64>,
    k: DMatrix<f64>,
    residual: f64,
    condition: f64,
    (measure, value, stable): (&'static str, f64, bool),
) -> Result<Riccati, RiccatiError> {
    if !stable {
        return Err(RiccatiError::NotStabilising { measure, value });
    }
    Ok(Riccati {
        x,
        k,
        residual,
        closed_loop: value,
        condition,
    })
}

/// Matrix sign function by scaled Newton iteration.
fn sign(h: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let n = h.nrows();
    let mut z = h.clone();
    for _ in 0..100 {
        let inv = z.clone().try_inverse()?;
        let det = z.determinant().abs();
        let c = if det > 0.0 && det.is_finite() {
            det.powf(-1.0 / n as f64)
        } else {
            1.0
        };
        let next = (&z * c + inv / c) * 0.5;
        let change = (&next - &z).norm() / next.norm();
        z = next;
        if change < 1e-14 {
            return Some(z);
        }
    }
    None
}

/// Continuous algebraic Riccati equation (optional cross term `S`).
pub fn care(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Riccati, RiccatiError> {
    let Prepared { n, r_inv, a0, q0 } = prepare(a, b, q, r, s)?;
    let g = b * &r_inv * b.transpose();
    let mut h = DMatrix::zeros(2 * n, 2 * n);
    h.view_mut((0, 0), (n, n)).copy_from(&a0);
    h.view_mut((0, n), (n, n)).copy_from(&(-&g));
    h.view_mut((n, 0), (n, n)).copy_from(&(-&q0));
    h.view_mut((n, n), (n, n)).copy_from(&(-a0.transpose()));
    let z = sign(&h).ok_or(RiccatiError::NoConvergence { iterations: 100 })?;
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
    let x = symmetric(
        lhs.svd(true, true)
            .solve(&rhs, 1e-14)
            .map_err(|_| RiccatiError::NoConvergence { iterations: 100 })?,
    );
    let cross = s.map_or_else(|| DMatrix::zeros(b.ncols(), n), |s| s.transpose());
    let k = &r_inv * (b.transpose() * &x + &cross);
    let residual_m = a.transpose() * &x + &x * a - (&x * b + cross.transpose()) * &k + q;
    let residual = residual_m.norm() / x.norm().max(1e-300);
    let closed = a - b * &k;
    let abscissa = crate::state_space::eigenvalues(&closed)
        .iter()
        .map(|l| l.re)
        .fold(f64::NEG_INFINITY, f64::max);
    let condition = x.norm() * r_inv.norm();
    solution(
        x,
        k,
        residual,
        condition,
        ("spectral abscissa", abscissa, abscissa < 0.0),
    )
}

/// Continuous Lyapunov `A X + X Aᵀ + Q = 0` for Hurwitz `A`: the Cayley transform
/// `A_d = (pI − A)⁻¹(pI + A)`, `Q_d = 2p (pI − A)⁻¹ Q (pI − A)⁻ᵀ` turns it into
/// `X = A_d X A_dᵀ + Q_d`; returns `X` and the relative residual of the continuous equation.
pub fn lyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<(DMatrix<f64>, f64), RiccatiError> {
    let n = a.nrows();
    if a.ncols() != n || q.shape() != (n, n) {
        return Err(RiccatiError::Shape("A and Q n×n"));
    }
    let p = a.norm().max(1e-300) / (n as f64).sqrt();
    let id = DMatrix::<f64>::identity(n, n);
    let m = (&id * p - a)
        .try_inverse()
        .ok_or(RiccatiError::NoConvergence { iterations: 0 })?;
    let ad = &m * (&id * p + a);
    let qd = &m * q * m.transpose() * (2.0 * p);
    let (x, _) = dlyap(&ad, &qd).map_err(|_| RiccatiError::NotStabilising {
        measure: "Cayley spectral radius",
        value: 1.0,
    })?;
    let x = symmetric(x);
    let residual = (a * &x + &x * a.transpose() + q).norm() / x.norm().max(1e-300);
    Ok((x, residual))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
        DMatrix::from_row_slice(r, c, v)
    }

    /// Scalar LQR: 2ax − b²x²/r + q = 0 → x = r(a + √(a² + b²q/r))/b².
    #[test]
    fn scalar_care_closed_form() {
        for (a, b, q, r) in [
            (1.0, 1.0, 1.0, 1.0),
            (-2.0, 0.5, 3.0, 0.1),
            (1e3, 1.0, 1.0, 1.0),
        ] {
            let sol = care(
                &m(1, 1, &[a]),
                &m(1, 1, &[b]),
                &m(1, 1, &[q]),
                &m(1, 1, &[r]),
                None,
            )
            .unwrap();
            let want = r * (a + (a * a + b * b * q / r).sqrt()) / (b * b);
            assert!(
                (sol.x[(0, 0)] - want).abs() < 1e-10 * want,
                "{} vs {want}",
                sol.x[(0, 0)]
            );
            assert!(sol.residual < 1e-10 && sol.closed_loop < 0.0);
        }
    }

    /// Double-integrator LQR (Q = I, R = 1): X = [[√3, 1], [1, √3]], K = [1, √3].
    #[test]
    fn double_integrator_care() {
        let sol = care(
            &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
            &m(2, 1, &[0.0, 1.0]),
            &DMatrix::identity(2, 2),
            &m(1, 1, &[1.0]),
            None,
        )
        .unwrap();
        let s3 = 3f64.sqrt();
        for (got, want) in sol.x.iter().zip([s3, 1.0, 1.0, s3]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert!((sol.k[(0, 0)] - 1.0).abs() < 1e-12 && (sol.k[(0, 1)] - s3).abs() < 1e-12);
        assert!(sol.residual < 1e-12);
    }

    /// Scalar DARE: x = a²x − a²b²x²/(r + b²x) + q, i.e. b²x² + (r − a²r − b²q)x − qr = 0.
    #[test]
    fn scalar_dare_closed_form() {
        for (a, b, q, r) in [
            (0.9, 1.0, 1.0, 1.0),
            (1.5, 0.3, 2.0, 0.5),
            (0.0, 1.0, 1.0, 1.0),
        ] {
            let sol = dare(
                &m(1, 1, &[a]),
                &m(1, 1, &[b]),
                &m(1, 1, &[q]),
                &m(1, 1, &[r]),
                None,
            )
            .unwrap();
            let (qa, qb, qc) = (b * b, r - a * a * r - b * b * q, -q * r);
            let want = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
            assert!((sol.x[(0, 0)] - want).abs() < 1e-12 * want.max(1.0));
            assert!(sol.residual < 1e-12 && sol.closed_loop < 1.0);
        }
    }

    /// Riccati difference iteration X ← AᵀXA − AᵀXB(R + BᵀXB)⁻¹BᵀXA + Q, independent of SDA.
    fn value_iteration(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let mut x = q.clone();
        for _ in 0..20_000 {
            let k = (r + b.transpose() * &x * b).try_inverse().unwrap() * b.transpose() * &x * a;
            x = a.transpose() * &x * a - a.transpose() * &x * b * k + q;
        }
        x
    }

    /// Singular A (a pure two-step delay chain in front of an unstable mode) and a
    /// cross-term problem: SDA agrees with the difference iteration, residual ≤ 1e-10.
    #[test]
    fn dare_with_singular_a_and_cross_term() {
        let a = m(3, 3, &[1.2, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        let b = m(3, 1, &[0.0, 0.0, 1.0]);
        let (q, r) = (DMatrix::identity(3, 3), m(1, 1, &[0.3]));
        let sol = dare(&a, &b, &q, &r, None).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
        let vi = value_iteration(&a, &b, &q, &r);
        assert!((&sol.x - &vi).norm() < 1e-9 * vi.norm());
        // Cross term: solve with S and compare with the transformed problem's iteration.
        let s = m(3, 1, &[0.1, 0.0, 0.2]);
        let sol = dare(&a, &b, &q, &r, Some(&s)).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
        let ri = r.clone().try_inverse().unwrap();
        let vi = value_iteration(
            &(&a - &b * &ri * s.transpose()),
            &b,
            &(&q - &s * &ri * s.transpose()),
            &r,
        );
        assert!((&sol.x - &vi).norm() < 1e-9 * vi.norm());
    }

    /// Unstabilisable pair: an unstable mode the input cannot reach has no stabilising solution.
    #[test]
    fn unstabilisable_pairs_are_errors() {
        let a = m(2, 2, &[1.5, 0.0, 0.0, 0.5]);
        let b = m(2, 1, &[0.0, 1.0]);
        assert!(dare(&a, &b, &DMatrix::identity(2, 2), &m(1, 1, &[1.0]), None).is_err());
        let ac = m(2, 2, &[1.0, 0.0, 0.0, -1.0]);
        assert!(care(&ac, &b, &DMatrix::identity(2, 2), &m(1, 1, &[1.0]), None).is_err());
    }

    /// Ill-conditioned CAREX-style case: widely separated time scales (1e-3 … 1e3 rad/s).
    #[test]
    fn widely_scaled_care() {
        let a = m(3, 3, &[-1e-3, 1.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0, -1e3]);
        let b = m(3, 1, &[0.0, 0.0, 1e3]);
        let sol = care(&a, &b, &DMatrix::identity(3, 3), &m(1, 1, &[1.0]), None).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
    }

    #[test]
    fn continuous_lyapunov() {
        let a = m(2, 2, &[-1.0, 2.0, 0.0, -3.0]);
        let q = m(2, 2, &[2.0, 0.5, 0.5, 1.0]);
        let (x, res) = lyap(&a, &q).unwrap();
        assert!(res < 1e-12, "{res}");
        // Scalar closed form: 2ax + q = 0.
        let (x1, _) = lyap(&m(1, 1, &[-0.25]), &m(1, 1, &[3.0])).unwrap();
        assert!((x1[(0, 0)] - 6.0).abs() < 1e-12);
        assert!(x.symmetric_eigenvalues().iter().all(|&l| l > 0.0));
    }
}
