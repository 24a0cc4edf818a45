//! The CAREX collection (Benner, Laub & Mehrmann, "A collection of benchmark examples for the
//! numerical solution of algebraic Riccati equations I: continuous-time case", TU
//! Chemnitz-Zwickau SPC 95_22, 1995), rebuilt from its published definitions: every example
//! but 6 and 20 (their data ship as files), at the default parameters and along the parameter
//! sweeps toward the ill-conditioned limits. Closed forms where the collection gives them.

use crate::common;

use common::extended::care_reference;
use common::{chain, diag, m, matches, trusted};
use lti::riccati::{care, Riccati, RiccatiError};
use nalgebra::DMatrix;

/// `care` on CAREX data given as `A, B, R, Q` (G = B R⁻¹ Bᵀ).
fn solve(a: &DMatrix<f64>, b: &DMatrix<f64>, r: &DMatrix<f64>, q: &DMatrix<f64>) -> Riccati {
    care(a, b, q, r, None).unwrap_or_else(|e| panic!("{e}"))
}

fn one() -> DMatrix<f64> {
    m(1, 1, &[1.0])
}

#[test]
fn carex_1_to_5_fixed_problems() {
    // 1: double integrator, X = [2 1; 1 2].
    let x = solve(
        &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
        &m(2, 1, &[0.0, 1.0]),
        &one(),
        &m(2, 2, &[1.0, 0.0, 0.0, 2.0]),
    );
    matches("carex 1", &x, &m(2, 2, &[2.0, 1.0, 1.0, 2.0]));
    // 2: X = (1 + √2)·Q.
    let q = m(2, 2, &[9.0, 6.0, 6.0, 4.0]);
    let x = solve(
        &m(2, 2, &[4.0, 3.0, -4.5, -3.5]),
        &m(2, 1, &[1.0, -1.0]),
        &one(),
        &q,
    );
    matches("carex 2", &x, &(&q * (1.0 + 2f64.sqrt())));
    // 3: a 4-state aircraft model.
    let a = m(
        4,
        4,
        &[
            0.0, 1.0, 0.0, 0.0, 0.0, -1.89, 0.39, -5.53, 0.0, -0.034, -2.98, 2.43, 0.034, -0.0011,
            -0.99, -0.21,
        ],
    );
    let b = m(4, 2, &[0.0, 0.0, 0.36, -1.6, -0.95, -0.032, 0.03, 0.0]);
    let q = m(
        4,
        4,
        &[
            2.313, 2.727, 0.688, 0.023, 2.727, 4.271, 1.148, 0.323, 0.688, 1.148, 0.313, 0.102,
            0.023, 0.323, 0.102, 0.083,
        ],
    );
    trusted("carex 3", &solve(&a, &b, &DMatrix::identity(2, 2), &q));
    // 4: an 8-state binary distillation column.
    let diag = [
        -0.991, -1.051, -1.118, -1.548, -1.640, -1.721, -1.823, -1.943,
    ];
    let upper = [0.529, 0.596, 0.596, 0.718, 0.799, 0.901, 1.021];
    let lower = [0.522, 0.522, 0.522, 0.922, 0.922, 0.922, 0.922];
    let a = DMatrix::from_fn(8, 8, |i, j| match j as i64 - i as i64 {
        0 => diag[i],
        1 => upper[i],
        -1 => lower[j],
        _ => 0.0,
    });
    let b1 = [3.84, 4.00, 37.60, 3.08, 2.36, 2.88, 3.08, 3.00];
    let b2 = [-2.88, -3.04, -2.80, -2.32, -3.32, -3.82, -4.12, -3.96];
    let b = DMatrix::from_fn(8, 2, |i, j| 0.001 * if j == 0 { b1[i] } else { b2[i] });
    let q12 = m(
        4,
        4,
        &[
            0.5, 0.0, 0.0, 0.1, 0.1, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
    );
    let mut q = DMatrix::zeros(8, 8);
    q.view_mut((0, 0), (4, 4)).fill_with_identity();
    q.view_mut((0, 4), (4, 4)).copy_from(&q12);
    q.view_mut((4, 0), (4, 4)).copy_from(&q12.transpose());
    q.view_mut((4, 4), (4, 4))
        .copy_from(&(DMatrix::identity(4, 4) * 0.1));
    trusted("carex 4", &solve(&a, &b, &DMatrix::identity(2, 2), &q));
    // 5: a 9-state tubular ammonia reactor.
    let a = m(
        9,
        9,
        &[
            -4.019, 5.12, 0.0, 0.0, -2.082, 0.0, 0.0, 0.0, 0.87, //
            -0.346, 0.986, 0.0, 0.0, -2.34, 0.0, 0.0, 0.0, 0.97, //
            -7.909, 15.407, -4.069, 0.0, -6.45, 0.0, 0.0, 0.0, 2.68, //
            -21.816, 35.606, -0.339, -3.87, -17.8, 0.0, 0.0, 0.0, 7.39, //
            -60.196, 98.188, -7.907, 0.34, -53.008, 0.0, 0.0, 0.0, 20.4, //
            0.0, 0.0, 0.0, 0.0, 94.0, -147.2, 0.0, 53.2, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 94.0, -147.2, 0.0, 0.0, //
            0.0, 0.0, 0.0, 0.0, 0.0, 12.8, 0.0, -31.6, 0.0, //
            0.0, 0.0, 0.0, 0.0, 12.8, 0.0, 0.0, 18.8, -31.6,
        ],
    );
    let bt = m(
        3,
        9,
        &[
            0.010, 0.003, 0.009, 0.024, 0.068, 0.0, 0.0, 0.0, 0.0, //
            -0.011, -0.021, -0.059, -0.162, -0.445, 0.0, 0.0, 0.0, 0.0, //
            -0.151, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
        ],
    );
    trusted(
        "carex 5",
        &solve(
            &a,
            &bt.transpose(),
            &DMatrix::identity(3, 3),
            &DMatrix::identity(9, 9),
        ),
    );
}

/// 7: `A = diag(1, −2)`, `B = [ε; 0]`, `Q = ones`: the unstable mode's control weakens as ε → 0
/// (X₁₁ grows like 2/ε²).
#[test]
fn carex_7_weakly_controllable_unstable_mode() {
    for eps in [1.0, 1e-2, 1e-4, 1e-6] {
        let dd: f64 = eps * eps;
        let s = (1.0 + dd).sqrt();
        let s2 = 2.0 + s;
        let want = m(
            2,
            2,
            &[
                (1.0 + s) / dd,
                1.0 / s2,
                1.0 / s2,
                (1.0 - dd / (s2 * s2)) / 4.0,
            ],
        );
        let x = solve(
            &m(2, 2, &[1.0, 0.0, 0.0, -2.0]),
            &m(2, 1, &[eps, 0.0]),
            &one(),
            &DMatrix::from_element(2, 2, 1.0),
        );
        matches(&format!("carex 7, ε = {eps:e}"), &x, &want);
    }
}

/// 8: `R = [1+ε 1; 1 1]` nearly singular as ε → 0.
#[test]
fn carex_8_nearly_singular_r() {
    for eps in [1e-2, 1e-4, 1e-6, 1e-8] {
        let x = solve(
            &m(2, 2, &[-0.1, 0.0, 0.0, -0.02]),
            &m(2, 2, &[0.1, 0.0, 0.001, 0.01]),
            &m(2, 2, &[1.0 + eps, 1.0, 1.0, 1.0]),
            &m(2, 2, &[100.0, 1000.0, 1000.0, 10000.0]),
        );
        trusted(&format!("carex 8, ε = {eps:e}"), &x);
    }
}

/// 9: `A = [0 ε; 0 0]` with ε up to 10⁶: `X = [s/ε 1; 1 s]`, `s = √(1 + 2ε)`.
#[test]
fn carex_9_large_coupling() {
    for eps in [1.0f64, 1e2, 1e4, 1e6] {
        let s = (1.0 + 2.0 * eps).sqrt();
        let x = solve(
            &m(2, 2, &[0.0, eps, 0.0, 0.0]),
            &m(2, 1, &[0.0, 1.0]),
            &one(),
            &DMatrix::identity(2, 2),
        );
        matches(
            &format!("carex 9, ε = {eps:e}"),
            &x,
            &m(2, 2, &[s / eps, 1.0, 1.0, s]),
        );
    }
}

/// 10: `A = [ε+1 1; 1 ε+1]`, `G = I`, `Q = ε²I`: the penalty vanishes as ε → 0.
#[test]
fn carex_10_vanishing_penalty() {
    for eps in [1e-1f64, 1e-3, 1e-5, 1e-7] {
        let d1 = eps + 1.0;
        let x1 = (2.0 * d1 + (2.0 * d1 * d1 + 2.0).sqrt() + 2f64.sqrt() * eps) / 2.0;
        let x2 = x1 / (x1 - d1);
        let x = solve(
            &m(2, 2, &[d1, 1.0, 1.0, d1]),
            &DMatrix::identity(2, 2),
            &DMatrix::identity(2, 2),
            &(DMatrix::identity(2, 2) * (eps * eps)),
        );
        matches(
            &format!("carex 10, ε = {eps:e}"),
            &x,
            &m(2, 2, &[x1, x2, x2, x1]),
        );
    }
}

/// 11: the Hamiltonian's eigenvalues `±ε ± i` reach the imaginary axis at ε = 0, where no
/// stabilising solution exists; for ε > 0, `X = [2 1; 1 1]` (closed loop `−ε ± i`).
#[test]
fn carex_11_eigenvalues_at_the_axis() {
    let data = |d: f64| {
        (
            m(2, 2, &[3.0 - d, 1.0, 4.0, 2.0 - d]),
            m(2, 1, &[1.0, 1.0]),
            m(
                2,
                2,
                &[4.0 * d - 11.0, 2.0 * d - 5.0, 2.0 * d - 5.0, 2.0 * d - 2.0],
            ),
        )
    };
    for eps in [1.0, 1e-2, 1e-4, 1e-6] {
        let (a, b, q) = data(eps);
        let x = solve(&a, &b, &one(), &q);
        matches(
            &format!("carex 11, ε = {eps:e}"),
            &x,
            &m(2, 2, &[2.0, 1.0, 1.0, 1.0]),
        );
        assert!(
            (x.closed_loop + eps).abs() < 1e-6 * eps.max(1e-3),
            "{}",
            x.closed_loop
        );
    }
    let (a, b, q) = data(0.0);
    match care(&a, &b, &q, &one(), None) {
        Err(RiccatiError::HamiltonianOnAxis { eigenvalue }) => {
            assert!((eigenvalue.im.abs() - 1.0).abs() < 1e-6, "{eigenvalue}")
        }
        other => panic!("carex 11, ε = 0: {other:?}"),
    }
}

/// 12: `A = ε·C·diag(1,2,3)·C` with ε = 10⁶: badly scaled (‖A‖ ~ 10⁶, ‖G‖ ~ 10⁻⁶).
#[test]
fn carex_12_badly_scaled() {
    for eps in [1.0, 1e2, 1e4, 1e6] {
        let c = DMatrix::identity(3, 3) - DMatrix::from_element(3, 3, 2.0 / 3.0);
        let a = &c * diag(&[1.0, 2.0, 3.0]) * &c * eps;
        let q = &c * diag(&[1.0 / eps, 1.0, eps]) * &c;
        let q = (&q + q.transpose()) * 0.5;
        let dd = eps * eps;
        let want =
            &c * diag(&[
                dd + (1.0 + dd * dd).sqrt(),
                2.0 * dd + (eps + 4.0 * dd * dd).sqrt(),
                3.0 * dd + eps * (1.0 + 9.0 * dd).sqrt(),
            ]) * &c;
        let x = solve(
            &a,
            &DMatrix::identity(3, 3),
            &(DMatrix::identity(3, 3) * eps),
            &q,
        );
        matches(&format!("carex 12, ε = {eps:e}"), &x, &want);
    }
}

/// 13: a stiff 4-state model (time scales 1 … 1/ε), and 14: the open-loop modes `±ε ± i` at
/// the axis as ε → 0; its closed loop keeps a pair at `−ε²/2 ± i`, 5·10⁻⁹ from the axis at
/// ε = 10⁻⁴ and 5·10⁻¹³ at 10⁻⁶ — closer than `√ε·‖H‖`, but a simple eigenvalue of the
/// Hamiltonian with condition number 1, told from the axis by structure. Solved, placed there,
/// and the forward error estimate covers the error against a double-double Newton reference.
#[test]
fn carex_13_stiff_and_14_near_the_axis() {
    for eps in [1e-2, 1e-4, 1e-6] {
        let a = m(
            4,
            4,
            &[
                0.0,
                0.4,
                0.0,
                0.0,
                0.0,
                0.0,
                0.345,
                0.0,
                0.0,
                -0.524 / eps,
                -0.465 / eps,
                0.262 / eps,
                0.0,
                0.0,
                0.0,
                -1.0 / eps,
            ],
        );
        let b = m(4, 1, &[0.0, 0.0, 0.0, 1.0 / eps]);
        let q = diag(&[1.0, 0.0, 1.0, 0.0]);
        trusted(
            &format!("carex 13, ε = {eps:e}"),
            &solve(&a, &b, &one(), &q),
        );
        let a = m(
            4,
            4,
            &[
                -eps, 1.0, 0.0, 0.0, -1.0, -eps, 0.0, 0.0, 0.0, 0.0, eps, 1.0, 0.0, 0.0, -1.0, eps,
            ],
        );
        let ones = DMatrix::from_element(4, 1, 1.0);
        let q = DMatrix::from_element(4, 4, 1.0);
        let want = -eps * eps / 2.0;
        let name = format!("carex 14, ε = {eps:e}");
        let x = solve(&a, &ones, &one(), &q);
        trusted(&name, &x);
        assert!(
            (x.closed_loop / want - 1.0).abs() < 1e-3,
            "{name}: closed loop {}",
            x.closed_loop
        );
        let (reference, corrections) = care_reference(&a, &ones, &q, &x.x, 4);
        assert!(
            corrections[3] < 1e-6 * corrections[0].max(1e-16),
            "{name}: the reference did not converge: {corrections:?}"
        );
        let err = (&x.x - &reference).norm() / reference.norm();
        assert!(
            err <= 10.0 * x.sensitivity().forward_error,
            "{name}: error {err:.2e} beyond the estimate {:.2e}",
            x.sensitivity().forward_error
        );
    }
}

/// A pair of open-loop modes `±10⁻⁸ ± i` (stable, then unstable) weakly driven and weighted
/// (`B = 10⁻⁴·I`, `Q = q·I`): `X = x·I` with `2ax − b²x² + q = 0`, the closed loop at
/// `−√(a² + b²q) = −1.2·10⁻⁸ ± i` — inside `√ε·‖H‖` of the axis, where a blanket rule would refuse,
/// but simple Hamiltonian eigenvalues, solved to the closed form. With `a = q = 0` the modes
/// sit on the axis unseen by the penalty: refused.
#[test]
fn pairs_a_hair_from_the_axis_are_solved_and_on_it_refused() {
    let (b, q) = (1e-4, 0.44e-8);
    for a in [-1e-8, 1e-8] {
        let am = m(2, 2, &[a, 1.0, -1.0, a]);
        let s = (a * a + b * b * q).sqrt();
        let want = DMatrix::identity(2, 2) * (q / (s - a));
        let x = solve(
            &am,
            &(DMatrix::identity(2, 2) * b),
            &DMatrix::identity(2, 2),
            &(DMatrix::identity(2, 2) * q),
        );
        let name = format!("a = {a:e}");
        matches(&name, &x, &want);
        assert!(
            (x.closed_loop / -s - 1.0).abs() < 1e-6,
            "{name}: closed loop {}",
            x.closed_loop
        );
    }
    let am = m(2, 2, &[0.0, 1.0, -1.0, 0.0]);
    let id = DMatrix::identity(2, 2);
    match care(&am, &(&id * b), &DMatrix::zeros(2, 2), &id, None) {
        Err(RiccatiError::UnseenBoundaryMode { mode }) => {
            assert!((mode.im.abs() - 1.0).abs() < 1e-12, "{mode}")
        }
        other => panic!("on the axis: {other:?}"),
    }
}

/// 15: `l` coupled first-order chains (n = 2l − 1), the default l = 20 and l = 40.
#[test]
fn carex_15_chain() {
    for l in [20usize, 40] {
        let n = 2 * l - 1;
        let mut a = DMatrix::zeros(n, n);
        let mut b = DMatrix::zeros(n, l);
        let mut c = DMatrix::zeros(l - 1, n);
        for i in 0..l - 1 {
            let (j, k) = (2 * i + 1, 2 * i);
            a[(k, k)] = -1.0;
            a[(j, k)] = 1.0;
            a[(j, j + 1)] = -1.0;
            b[(k, i)] = 1.0;
            c[(i, j)] = 1.0;
        }
        a[(n - 1, n - 1)] = -1.0;
        b[(n - 1, l - 1)] = 1.0;
        let q = c.transpose() * c * 10.0;
        trusted(
            &format!("carex 15, l = {l}"),
            &solve(&a, &b, &DMatrix::identity(l, l), &q),
        );
    }
}

/// 16: a circulant (periodic) chain, n = 64 and 128, with its closed form from the DFT of the
/// scalar solutions.
#[test]
fn carex_16_circulant() {
    for n in [64usize, 128] {
        let mut a = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => -2.0,
            1 => 1.0,
            _ => 0.0,
        });
        a[(n - 1, 0)] = 1.0;
        a[(0, n - 1)] = 1.0;
        let tau = std::f64::consts::TAU;
        let su: Vec<f64> = (0..n)
            .map(|k| {
                let c = libm::cos(tau * k as f64 / n as f64);
                -2.0 + 2.0 * c + (5.0 - 8.0 * c + 4.0 * c * c).sqrt()
            })
            .collect();
        let col: Vec<f64> = (0..n)
            .map(|j| {
                su.iter()
                    .enumerate()
                    .map(|(k, s)| s * libm::cos(tau * (j * k) as f64 / n as f64))
                    .sum::<f64>()
                    / n as f64
            })
            .collect();
        let want = DMatrix::from_fn(n, n, |i, j| col[i.abs_diff(j)]);
        let id = DMatrix::identity(n, n);
        let x = solve(&a, &id, &id, &id);
        matches(&format!("carex 16, n = {n}"), &x, &want);
    }
}

/// 17: a pure integrator chain observed at its end, n = 21 (default) and 11: the corner of `X`
/// is `√(Q₀·R)`, the only closed-form entry; the closed loop's slowest pair is at `−sin(π/2n)`.
/// The solution grows like binomial coefficients (‖X‖ ≈ 10⁹ at n = 21).
#[test]
fn carex_17_integrator_chain() {
    for n in [11usize, 21] {
        let (a, b) = chain(n);
        let mut q = DMatrix::zeros(n, n);
        q[(0, 0)] = 1.0;
        let slowest = -libm::sin(std::f64::consts::PI / (2 * n) as f64);
        let x = solve(&a, &b, &one(), &q);
        trusted(&format!("carex 17, n = {n}"), &x);
        assert!(
            (x.closed_loop - slowest).abs() < 10.0 * x.sensitivity().forward_error,
            "{} vs {slowest}",
            x.closed_loop
        );
        let corner = x.x[(0, n - 1)];
        assert!(
            (corner - 1.0).abs() <= 10.0 * x.sensitivity().forward_error * x.x.norm(),
            "n = {n}: X[1, n] = {corner} (estimate {:.1e})",
            x.sensitivity().forward_error
        );
    }
}

/// 18: a heat equation by finite elements, n = 100 (default) and 160; 19: a string of l = 30
/// (default) and 80 masses and springs.
#[test]
fn carex_18_heat_and_19_springs() {
    for n in [100usize, 160] {
        let (a, b, q) = heat(n);
        trusted(&format!("carex 18, n = {n}"), &solve(&a, &b, &one(), &q));
    }
    for l in [30usize, 80] {
        let (mu, kappa, delta) = (4.0, 1.0, 4.0);
        let n = 2 * l;
        let mut a = DMatrix::zeros(n, n);
        a.view_mut((0, l), (l, l)).fill_with_identity();
        for i in 0..l {
            let ends = if i == 0 || i == l - 1 { 1.0 } else { 2.0 };
            a[(l + i, i)] = -kappa * ends / mu;
            if i + 1 < l {
                a[(l + i, i + 1)] = kappa / mu;
                a[(l + i + 1, i)] = kappa / mu;
            }
            a[(l + i, l + i)] = -delta / mu;
        }
        let mut b = DMatrix::zeros(n, 2);
        b[(l, 0)] = 1.0 / mu;
        b[(n - 1, 1)] = -1.0 / mu;
        let id = DMatrix::identity(n, n);
        trusted(
            &format!("carex 19, l = {l}"),
            &solve(&a, &b, &DMatrix::identity(2, 2), &id),
        );
    }
}

/// CAREX 18's data: the Gram matrix M of hat functions, `A = M⁻¹·α(n+1)·tridiag(1,−2,1)`,
/// `B = M⁻¹b`, `Q = cᵀc` with `b`, `c` the hat functions integrated over [0.2, 0.3].
fn heat(n: usize) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let (alpha, beta, gamma) = (0.01, 1.0, 1.0);
    let (lo, hi) = (0.2, 0.3);
    let h = (n + 1) as f64;
    let tri = |d: f64, o: f64| {
        DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => d,
            1 => o,
            _ => 0.0,
        })
    };
    let gram = tri(4.0, 1.0) / (6.0 * h);
    let stiffness = tri(-2.0, 1.0) * (alpha * h);
    let lu = gram.lu();
    let a = lu.solve(&stiffness).unwrap();
    // ∫ over [lo, hi] of the hat function centred at i/(n+1) (support ((i−1)/h, (i+1)/h)).
    let hat = |i: usize, scale: f64| {
        let i = i as f64;
        let (b1, b2) = (((i - 1.0) / h).max(lo), ((i + 1.0) / h).min(hi));
        if b1 >= b2 {
            return 0.0;
        }
        let mut v = b2 - b1;
        let t = b2.min(i / h);
        if b1 < t {
            v += h * (t * t - b1 * b1) / 2.0 + i * (b1 - t);
        }
        let t = b1.max(i / h);
        if t < b2 {
            v -= h * (b2 * b2 - t * t) / 2.0 + i * (t - b2);
        }
        scale * v
    };
    let bvec = DMatrix::from_fn(n, 1, |i, _| hat(i + 1, beta));
    let c = DMatrix::from_fn(1, n, |_, j| hat(j + 1, gamma));
    (a, lu.solve(&bvec).unwrap(), c.transpose() * c)
}
