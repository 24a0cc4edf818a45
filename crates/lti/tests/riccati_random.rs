//! Random problems n = 5 … 160, with and without cross terms, continuous and discrete; and the
//! condition estimate checked against what perturbing the data actually does.

use crate::common;

use common::random::{gaussian, problem, Data};
use common::{m, trusted};
use lti::riccati::{care, dare, Solver};
use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;

#[test]
fn random_problems_up_to_160_states() {
    for (name, solver, discrete) in [("care", care as Solver, false), ("dare", dare, true)] {
        for n in [5usize, 10, 20, 40, 80, 160] {
            for cross in [false, true] {
                let Data { a, b, q, r, s } = problem(n, n as u64, cross, discrete);
                let x = solver(&a, &b, &q, &r, s.as_ref())
                    .unwrap_or_else(|e| panic!("{name} n = {n}, cross {cross}: {e}"));
                trusted(&format!("{name} n = {n}, cross {cross}"), &x);
                assert!(
                    x.sensitivity().forward_error < 1e-8,
                    "{name} n = {n}: forward error {:.1e}",
                    x.sensitivity().forward_error
                );
            }
        }
    }
}

/// A named problem: (name, solver, A, B, Q, R).
type Case = (
    String,
    Solver,
    DMatrix<f64>,
    DMatrix<f64>,
    DMatrix<f64>,
    DMatrix<f64>,
);

/// Perturbing the data by a relative `δ` moves the solution by at most about `κ·δ` and, in the
/// worst of a few random directions, by more than a tenth of it: the condition number predicts
/// the sensitivity within a factor of ten, on the ill-conditioned CAREX and DAREX families.
#[test]
fn the_condition_number_predicts_the_effect_of_perturbed_data() {
    let two = |v: &[f64]| m(2, 2, v);
    let one = m(1, 1, &[1.0]);
    // (name, solver, A, B, Q, R) of CAREX 7, 9, 10, 11 and DAREX 12 toward their limits.
    let mut cases: Vec<Case> = Vec::new();
    for eps in [1e-2, 1e-4] {
        cases.push((
            format!("carex 7, ε = {eps:e}"),
            care,
            two(&[1.0, 0.0, 0.0, -2.0]),
            m(2, 1, &[eps, 0.0]),
            DMatrix::from_element(2, 2, 1.0),
            one.clone(),
        ));
        // CAREX 11 only at ε = 10⁻²: at 10⁻⁴ its Hamiltonian pair ±ε ± i is so nearly
        // defective that a 10⁻⁹ change of Q can put both on the axis (no solution to compare).
        if eps > 1e-3 {
            cases.push((
                format!("carex 11, ε = {eps:e}"),
                care,
                two(&[3.0 - eps, 1.0, 4.0, 2.0 - eps]),
                m(2, 1, &[1.0, 1.0]),
                two(&[
                    4.0 * eps - 11.0,
                    2.0 * eps - 5.0,
                    2.0 * eps - 5.0,
                    2.0 * eps - 2.0,
                ]),
                one.clone(),
            ));
        }
        let d1 = eps + 1.0;
        cases.push((
            format!("carex 10, ε = {eps:e}"),
            care,
            two(&[d1, 1.0, 1.0, d1]),
            DMatrix::identity(2, 2),
            DMatrix::identity(2, 2) * (eps * eps),
            DMatrix::identity(2, 2),
        ));
    }
    for eps in [1e2, 1e4] {
        cases.push((
            format!("carex 9, ε = {eps:e}"),
            care,
            two(&[0.0, eps, 0.0, 0.0]),
            m(2, 1, &[0.0, 1.0]),
            DMatrix::identity(2, 2),
            one.clone(),
        ));
        cases.push((
            format!("darex 12, ε = {eps:e}"),
            dare,
            two(&[0.0, eps, 0.0, 0.0]),
            m(2, 1, &[0.0, 1.0]),
            DMatrix::identity(2, 2),
            one.clone(),
        ));
    }
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
    let delta = 1e-9;
    for (name, solver, a, b, q, r) in cases {
        let x = solver(&a, &b, &q, &r, None).unwrap();
        let predicted = x.sensitivity().condition * delta;
        let mut worst: f64 = 0.0;
        for _ in 0..8 {
            let mut nudge = |mat: &DMatrix<f64>, symmetric: bool| {
                let e = gaussian(&mut rng, mat.nrows(), mat.ncols());
                let e = if symmetric {
                    (&e + e.transpose()) * 0.5
                } else {
                    e
                };
                let size = e.norm().max(f64::MIN_POSITIVE);
                mat + e * (delta * mat.norm() / size)
            };
            let (ap, qp, rp) = (nudge(&a, false), nudge(&q, true), nudge(&r, true));
            let moved = solver(&ap, &b, &qp, &rp, None).unwrap();
            worst = worst.max((&moved.x - &x.x).norm() / x.x.norm());
        }
        assert!(
            worst <= 2.0 * predicted && worst >= predicted / 10.0,
            "{name}: moved {worst:.2e}, predicted κ·δ = {predicted:.2e} (κ {:.2e})",
            x.sensitivity().condition
        );
    }
}
