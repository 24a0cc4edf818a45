//! Closed forms and independent iterations for the Riccati and Lyapunov solvers.

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
