//! Continuous H2 synthesis (SB10HD problem) on the double-integrator LQG problem, whose Riccati
//! solutions have a closed form: ẍ = u + √w·w₁, y = x + √v·w₂, z = [√q·x; √r·u].
//!
//! Control CARE (A = [0 1; 0 0], B = [0; 1], Q = diag(q, 0), R = r):
//! x₂ = √(q r), x₃ = √(2 r x₂), x₁ = x₂ x₃ / r.
//! Filter CARE (dual, W = diag(0, w), V = v): y₂ = √(w v), y₁ = √(2 v y₂), y₃ = y₁ y₂ / v.
//! Optimal cost ‖T_zw‖₂² = trace(B1ᵀ X B1) + trace(R F Y Fᵀ), F = −[x₂ x₃]/r
//! (Zhou, Doyle & Glover, Theorem 14.7).

use design::h2::{h2_norm_continuous, h2syn_continuous, GeneralizedPlant};
use nalgebra::DMatrix;

fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
    DMatrix::from_row_slice(r, c, v)
}

fn plant(q: f64, r: f64, w: f64, v: f64) -> GeneralizedPlant {
    GeneralizedPlant {
        a: m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
        b1: m(2, 2, &[0.0, 0.0, w.sqrt(), 0.0]),
        b2: m(2, 1, &[0.0, 1.0]),
        c1: m(2, 2, &[q.sqrt(), 0.0, 0.0, 0.0]),
        c2: m(1, 2, &[1.0, 0.0]),
        d12: m(2, 1, &[0.0, r.sqrt()]),
        d21: m(1, 2, &[0.0, v.sqrt()]),
    }
}

fn closed_form(q: f64, r: f64, w: f64, v: f64) -> f64 {
    let x2 = (q * r).sqrt();
    let x3 = (2.0 * r * x2).sqrt();
    let y2 = (w * v).sqrt();
    let y1 = (2.0 * v * y2).sqrt();
    let y3 = y1 * y2 / v;
    let control = w * x3; // trace(B1ᵀ X B1) = w·x₃
    let filter = (x2 * x2 * y1 + 2.0 * x2 * x3 * y2 + x3 * x3 * y3) / r;
    (control + filter).sqrt()
}

#[test]
fn double_integrator_lqg_matches_the_closed_form_optimum() {
    for &(q, r, w, v) in &[
        (1.0, 0.01, 1.0, 1e-4),
        (100.0, 1.0, 0.1, 1e-2),
        (1.0, 1e-6, 1e3, 1e-8),
    ] {
        let p = plant(q, r, w, v);
        let k = h2syn_continuous(&p).unwrap();
        let want = closed_form(q, r, w, v);
        assert!(k.spectral_abscissa < 0.0, "stable");
        assert!(
            (k.h2_norm / want - 1.0).abs() < 1e-8,
            "q {q} r {r} w {w} v {v}: {} vs closed form {want}",
            k.h2_norm
        );
        // The norm again, independently, from the closed loop's gramian.
        let again = h2_norm_continuous(&p.close(&k.k)).unwrap();
        assert!((again / k.h2_norm - 1.0).abs() < 1e-10);
    }
}

#[test]
fn perturbing_the_optimal_controller_never_helps() {
    let p = plant(1.0, 0.01, 1.0, 1e-4);
    let k = h2syn_continuous(&p).unwrap();
    for (i, eps) in [(0usize, 1e-3), (1, -1e-3), (2, 1e-3), (3, -1e-3)] {
        let mut worse = k.k.clone();
        worse.a[(i / 2, i % 2)] *= 1.0 + eps;
        let n = h2_norm_continuous(&p.close(&worse)).unwrap_or(f64::INFINITY);
        assert!(
            n >= k.h2_norm * (1.0 - 1e-12),
            "perturbation {i} gave {n} < {}",
            k.h2_norm
        );
    }
}
