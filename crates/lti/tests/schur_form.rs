//! The Schur form on a badly scaled matrix: the closed loop of a candidate solution met by the
//! thesis's 29-state H2 design at 20 kHz (`servo thesis`), of norm 3.6·10¹⁸ and spectral radius
//! 0.99998 (after balancing, as LAPACK's eigensolver and ours do). Unbalanced, faer's real QZ
//! returned eigenvalues −15.5 and 13.1 — rounding at that norm — and the Riccati solver called
//! the solution destabilising. The form is of the balanced matrix: its eigenvalues are the
//! matrix's and the Stein equation on it holds to rounding.

use lti::schur_lyapunov::{SchurForm, Side};
use nalgebra::DMatrix;

fn closed_loop() -> DMatrix<f64> {
    let text = include_str!("data/h2_closed_loop_29.txt");
    let v: Vec<f64> = text.lines().map(|l| l.trim().parse().unwrap()).collect();
    DMatrix::from_column_slice(29, 29, &v)
}

#[test]
fn a_badly_scaled_matrix_is_reduced_balanced() {
    let a = closed_loop();
    let s = SchurForm::new(&a).expect("a Schur form");
    let reference = lti::eigenvalues(&a);
    let radius = reference.iter().map(|l| l.norm()).fold(0.0, f64::max);
    assert!(radius < 1.0, "{radius}");
    for l in s.eigenvalues() {
        let nearest = reference
            .iter()
            .map(|r| (r - l).norm())
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 1e-8, "{l}: {nearest:e} from the nearest");
    }
    let w = DMatrix::from_fn(29, 29, |i, j| 1.0 + ((i * 7 + j * 3) % 5) as f64);
    let z = s.discrete(&w, Side::Transposed);
    let middle = a.transpose() * &z * &a;
    let terms = middle.norm() + w.norm() + z.norm();
    assert!((middle + &w - &z).norm() < 1e-12 * terms);
}
