//! The DAREX collection (Benner, Laub & Mehrmann, "A collection of benchmark examples for the
//! numerical solution of algebraic Riccati equations II: discrete-time case", TU
//! Chemnitz-Zwickau SPC 95_23, 1995), rebuilt from its published definitions: every example
//! with a nonsingular R (3 and 4 have a singular R, which needs the extended pencil and is
//! refused by name), closed forms where the collection gives them; then the cases the loop's
//! own design meets: delay chains (singular A) and unstable modes the penalty does not see.

use crate::common;

use common::{chain, diag, m, matches, trusted};
use lti::riccati::{dare, Riccati, RiccatiError, Route};
use nalgebra::DMatrix;

fn solve(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Riccati {
    dare(a, b, q, r, s).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn darex_fixed_problems() {
    // 1: X = (1 + √5)/2 · Q.
    let q = m(2, 2, &[9.0, 6.0, 6.0, 4.0]);
    let x = solve(
        &m(2, 2, &[4.0, 3.0, -4.5, -3.5]),
        &m(2, 1, &[1.0, -1.0]),
        &q,
        &m(1, 1, &[1.0]),
        None,
    );
    matches("darex 1", &x, &(&q * ((1.0 + 5f64.sqrt()) / 2.0)));
    // 2: two inputs, a stable plant.
    let x = solve(
        &diag(&[0.9512, 0.9048]),
        &m(2, 2, &[4.877, 4.877, -1.1895, 3.569]),
        &diag(&[0.005, 0.02]),
        &diag(&[1.0 / 3.0, 3.0]),
        None,
    );
    trusted("darex 2", &x);
    // 3 and 4: R singular (the extended pencil's domain): refused by name.
    let r3 = m(1, 1, &[0.0]);
    assert!(matches!(
        dare(
            &m(2, 2, &[2.0, -1.0, 1.0, 0.0]),
            &m(2, 1, &[1.0, 0.0]),
            &diag(&[0.0, 1.0]),
            &r3,
            None
        ),
        Err(RiccatiError::SingularR)
    ));
    // 5: singular A, X = [1 2; 2 2+√5].
    let x = solve(
        &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
        &m(2, 1, &[0.0, 1.0]),
        &m(2, 2, &[1.0, 2.0, 2.0, 4.0]),
        &m(1, 1, &[1.0]),
        None,
    );
    matches("darex 5", &x, &m(2, 2, &[1.0, 2.0, 2.0, 2.0 + 5f64.sqrt()]));
    // 6: two lightly damped oscillators.
    let mut a = DMatrix::identity(4, 4) * 0.998;
    a[(0, 1)] = 0.067;
    a[(1, 0)] = -0.067;
    a[(2, 3)] = 0.153;
    a[(3, 2)] = -0.153;
    let b = m(
        4,
        2,
        &[0.0033, 0.02, 0.1, -0.0007, 0.04, 0.0073, -0.0028, 0.1],
    );
    let q = m(
        4,
        4,
        &[
            1.87, 0.0, 0.0, -0.244, 0.0, 0.744, 0.205, 0.0, 0.0, 0.205, 0.589, 0.0, -0.244, 0.0,
            0.0, 1.048,
        ],
    );
    trusted(
        "darex 6",
        &solve(&a, &b, &q, &DMatrix::identity(2, 2), None),
    );
    // 7: an unstable 4-state aircraft model.
    let a = m(
        4,
        4,
        &[
            0.98475, -0.079903, 0.0009054, -0.0010765, 0.041588, 0.99899, -0.035855, 0.012684,
            -0.54662, 0.044916, -0.32991, 0.19318, 2.6624, -0.10045, -0.92455, -0.26325,
        ],
    );
    let b = m(
        4,
        2,
        &[
            0.0037112, 0.0007361, -0.087051, 9.3411e-6, -1.19844, -4.1378e-4, -3.1927, 9.2535e-4,
        ],
    );
    trusted(
        "darex 7",
        &solve(
            &a,
            &b,
            &(DMatrix::identity(4, 4) * 0.01),
            &DMatrix::identity(2, 2),
            None,
        ),
    );
    // 8: a mode at −0.999982, almost on the unit circle.
    let b = -DMatrix::from_fn(4, 4, |i, j| if j >= i { 1.0 } else { 0.0 })
        + DMatrix::identity(4, 4) * 2.0;
    let mut c = DMatrix::from_fn(4, 4, |i, j| if j >= i { 1.0 } else { 0.0 });
    c[(0, 2)] += 1.0;
    c[(1, 3)] += 1.0;
    c[(3, 3)] += 3.0;
    let q0 = m(
        4,
        4,
        &[
            2.0, -1.0, 0.0, 0.0, -1.0, 2.0, -1.0, 0.0, 0.0, -1.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
    );
    let inner = m(
        4,
        4,
        &[
            0.4, 0.0, 0.0, 0.0, 1.0, 0.6, 0.0, 0.0, 0.0, 1.0, 0.8, 0.0, 0.0, 0.0, 0.0, -0.999982,
        ],
    );
    let a = &b * inner * &c;
    let q = c.transpose() * q0 * &c;
    trusted(
        "darex 8",
        &solve(&a, &b, &q, &DMatrix::identity(4, 4), None),
    );
    // 9: a 5-state chemical plant.
    let a = m(
        5,
        5,
        &[
            95.407, 1.9643, 0.3597, 0.0673, 0.019, 40.849, 41.317, 16.084, 4.4679, 1.1971, 12.217,
            26.326, 36.149, 15.93, 12.383, 4.1118, 12.858, 27.209, 21.442, 40.976, 0.1305, 0.5808,
            1.875, 3.6162, 94.28,
        ],
    ) * 0.01;
    let bt = m(
        2,
        5,
        &[
            0.0434, 2.6606, 3.753, 3.6076, 0.4617, -0.0122, -1.0453, -5.51, -6.6, -0.9148,
        ],
    ) * 0.01;
    trusted(
        "darex 9",
        &solve(
            &a,
            &bt.transpose(),
            &DMatrix::identity(5, 5),
            &DMatrix::identity(2, 2),
            None,
        ),
    );
    // 10: a cross term (S = CᵀD) and two delay chains (singular A).
    let mut a = DMatrix::zeros(6, 6);
    for k in [0, 3] {
        a[(k, k + 1)] = 1.0;
        a[(k + 1, k + 2)] = 1.0;
    }
    let b = m(
        6,
        2,
        &[0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    );
    let c = m(
        2,
        6,
        &[1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, -1.0, 0.0],
    );
    let d = m(2, 2, &[1.0, 0.0, 1.0, 0.0]);
    let r = DMatrix::identity(2, 2) + d.transpose() * &d;
    let x = solve(
        &a,
        &b,
        &(c.transpose() * &c),
        &r,
        Some(&(c.transpose() * d)),
    );
    trusted("darex 10", &x);
    // 11: a 9-state boiler model.
    let a = m(
        9,
        9,
        &[
            870.1, 135.0, 11.59, 0.5014, -37.22, 0.3484, 0.0, 4.242, 7.249, //
            76.55, 897.4, 12.72, 0.5504, -40.16, 0.3743, 0.0, 4.53, 7.499, //
            -127.2, 357.5, 817.0, 1.455, -102.8, 0.987, 0.0, 11.85, 18.72, //
            -363.5, 633.9, 74.91, 796.6, -273.5, 2.653, 0.0, 31.72, 48.82, //
            -960.0, 1645.9, -128.9, -5.597, 71.42, 7.108, 0.0, 84.52, 125.9, //
            -664.4, 112.96, -88.89, -3.854, 84.47, 13.6, 0.0, 144.3, 101.6, //
            -410.2, 693.0, -54.71, -2.371, 66.49, 12.49, 0.1063, 99.97, 69.67, //
            -179.9, 301.7, -23.93, -1.035, 60.59, 22.16, 0.0, 213.9, 35.54, //
            -345.1, 580.4, -45.96, -1.989, 105.6, 19.86, 0.0, 219.1, 215.2,
        ],
    ) * 0.001;
    let bt = m(
        3,
        9,
        &[
            4.76, -0.5701, -83.68, 0.879, -4.773, -2.73, 1.482, -13.12, 8.876, 3.892, -35.13, 24.8,
            10.34, -92.75, 66.8, 7.203, -61.59, 38.34, 4.454, -36.83, 20.29, 1.971, -15.54, 6.937,
            3.773, -30.28, 14.69,
        ],
    );
    // The published B is 9 × 3 given column by column.
    let b = DMatrix::from_fn(9, 3, |i, j| bt[(i / 3, (i % 3) * 3 + j)]) * 1e-4;
    let mut q = DMatrix::zeros(9, 9);
    q[(0, 0)] = 50.0;
    q[(4, 4)] = 50.0;
    trusted(
        "darex 11",
        &solve(&a, &b, &q, &DMatrix::identity(3, 3), None),
    );
}

/// 12: `A = [0 ε; 0 0]` up to ε = 10⁶: `X = diag(1, 1 + ε²)`.
#[test]
fn darex_12_large_coupling() {
    for eps in [1.0f64, 1e2, 1e4, 1e6] {
        let x = solve(
            &m(2, 2, &[0.0, eps, 0.0, 0.0]),
            &m(2, 1, &[0.0, 1.0]),
            &DMatrix::identity(2, 2),
            &m(1, 1, &[1.0]),
            None,
        );
        matches(
            &format!("darex 12, ε = {eps:e}"),
            &x,
            &diag(&[1.0, 1.0 + eps * eps]),
        );
    }
}

/// 13: `A = U·diag(0, 1, 3)·U`, `R = Q = ε·I`: `X = ε·U·diag(1, (1+√5)/2, (9+√85)/2)·U`.
#[test]
fn darex_13_scaled() {
    for eps in [1e-6, 1.0, 1e6] {
        let u = DMatrix::identity(3, 3) - DMatrix::from_element(3, 3, 2.0 / 3.0);
        let a = &u * diag(&[0.0, 1.0, 3.0]) * &u;
        let id = DMatrix::identity(3, 3);
        let want = &u * diag(&[1.0, (1.0 + 5f64.sqrt()) / 2.0, (9.0 + 85f64.sqrt()) / 2.0]) * &u;
        let x = solve(&a, &id, &(&id * eps), &(&id * eps), None);
        matches(&format!("darex 13, ε = {eps:e}"), &x, &(want * eps));
    }
}

/// 14: a first-order lag `α = 1 − D/τ` behind three delays, τ up to 10⁸: the lag's pole at
/// `1 − 10⁻⁸`, almost on the unit circle.
#[test]
fn darex_14_slow_lag_behind_delays() {
    for tau in [1e2f64, 1e4, 1e6, 1e8] {
        let (r, k, d) = (0.25, 1.0, 1.0);
        let alpha = 1.0 - d / tau;
        let beta = k * d / tau;
        let mut a = DMatrix::zeros(4, 4);
        a[(0, 0)] = alpha;
        for i in 1..4 {
            a[(i, i - 1)] = 1.0;
        }
        let mut b = DMatrix::zeros(4, 1);
        b[(0, 0)] = beta;
        let q = diag(&[0.0, 0.0, 0.0, 1.0]);
        let dd = (alpha + 1.0) * (alpha - 1.0);
        let s = (r * tau / k / d) * tau / k / d;
        let mut want = DMatrix::identity(4, 4);
        want[(0, 0)] = s * dd / 2.0 + 0.5 + (0.25 * (s * dd + 1.0).powi(2) + s).sqrt();
        let x = solve(&a, &b, &q, &m(1, 1, &[r]), None);
        matches(&format!("darex 14, τ = {tau:e}"), &x, &want);
    }
}

/// 15: a pure delay line of n = 100 and 160 (A nilpotent and singular): `X = diag(1 … n)`.
#[test]
fn darex_15_delay_line() {
    for n in [100usize, 160] {
        let (a, b) = chain(n);
        let want = DMatrix::from_diagonal(&nalgebra::DVector::from_fn(n, |i, _| (i + 1) as f64));
        let x = solve(&a, &b, &DMatrix::identity(n, n), &m(1, 1, &[1.0]), None);
        matches(&format!("darex 15, n = {n}"), &x, &want);
    }
}

/// An unstable mode the penalty does not see (stabilisable, not detectable): doubling alone
/// converges to the smallest solution, which leaves the mode unstable; the solver reaches the
/// stabilising one. Scalar `a = 2, b = 1, q = 0, r = 1`: `x² = 3x`, the stabilising root is
/// `x = 3` (closed loop 0.5, where `x = 0` leaves it at 2); and a 2-state plant whose unseen
/// mode at 1.5 must be moved while the seen one at 0.5 is weighted.
#[test]
fn unseen_unstable_modes_are_stabilised() {
    let x = solve(
        &m(1, 1, &[2.0]),
        &m(1, 1, &[1.0]),
        &m(1, 1, &[0.0]),
        &m(1, 1, &[1.0]),
        None,
    );
    matches("scalar, unseen", &x, &m(1, 1, &[3.0]));
    assert_eq!(x.route, Route::Regularised);
    assert!((x.closed_loop - 0.5).abs() < 1e-12, "{}", x.closed_loop);
    let x = solve(
        &diag(&[1.5, 0.5]),
        &m(2, 1, &[1.0, 1.0]),
        &diag(&[0.0, 1.0]),
        &m(1, 1, &[1.0]),
        None,
    );
    trusted("2-state, unseen", &x);
    assert!(x.closed_loop < 1.0);
    // With the unstable mode out of the input's reach too, the reason is named.
    match dare(
        &diag(&[1.5, 0.5]),
        &m(2, 1, &[0.0, 1.0]),
        &diag(&[0.0, 1.0]),
        &m(1, 1, &[1.0]),
        None,
    ) {
        Err(RiccatiError::Unstabilisable { mode }) => {
            assert!((mode.re - 1.5).abs() < 1e-12 && mode.im == 0.0, "{mode}")
        }
        other => panic!("{other:?}"),
    }
    // A mode on the unit circle that the penalty does not see: moving it costs input and gains
    // nothing, so the optimal loop leaves it there and no solution stabilises; named.
    match dare(
        &diag(&[1.0, 0.5]),
        &m(2, 1, &[1.0, 1.0]),
        &diag(&[0.0, 1.0]),
        &m(1, 1, &[1.0]),
        None,
    ) {
        Err(RiccatiError::UnseenBoundaryMode { mode }) => {
            assert!((mode.re - 1.0).abs() < 1e-12, "{mode}")
        }
        other => panic!("{other:?}"),
    }
}

/// A longer delay chain behind an unstable mode (the loop's own structure): n = 12 and 40.
#[test]
fn unstable_mode_behind_a_delay_line() {
    for n in [12usize, 40] {
        let (mut a, b) = chain(n);
        a[(0, 0)] = 1.2;
        let mut q = DMatrix::zeros(n, n);
        q[(0, 0)] = 1.0;
        let x = solve(&a, &b, &q, &m(1, 1, &[1e-2]), None);
        trusted(&format!("delay line n = {n}"), &x);
    }
}
