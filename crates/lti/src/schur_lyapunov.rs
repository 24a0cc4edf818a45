//! Lyapunov and Stein equations for many right-hand sides with one matrix, by the complex Schur
//! form (Bartels–Stewart): `A = U T Uᴴ` is computed once (O(n³)), after which each equation is a
//! column-by-column triangular substitution (O(n³), no iteration). What Newton's refinement of a
//! Riccati solution and the Riccati condition estimate need: the closed loop stays the same while
//! the right-hand side changes.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// The complex Schur form `A = U T Uᴴ` of a real square matrix.
pub struct SchurForm {
    u: DMatrix<Complex64>,
    t: DMatrix<Complex64>,
}

/// Which operator of `A` an equation is written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    /// `AᵀZ + ZA + W = 0` or `Z = AᵀZA + W` (the closed loop of a control Riccati equation).
    Transposed,
    /// `AZ + ZAᵀ + W = 0` or `Z = AZAᵀ + W` (a gramian; the adjoint of the other).
    Plain,
}

impl SchurForm {
    /// QR sweeps allowed per row of the matrix (LAPACK allows 30 per eigenvalue).
    pub const ITERATIONS_PER_ROW: usize = 100;

    /// The Schur form of `a`, or `None` when the QR iteration does not converge within
    /// [`SchurForm::ITERATIONS_PER_ROW`] sweeps per row (nalgebra's unbounded iteration at
    /// machine precision can cycle for ever on some matrices: a design study met one).
    pub fn new(a: &DMatrix<f64>) -> Option<Self> {
        let complex = a.map(|v| Complex64::new(v, 0.0));
        let limit = Self::ITERATIONS_PER_ROW * a.nrows().max(1);
        let (u, t) = nalgebra::Schur::try_new(complex, f64::EPSILON, limit)?.unpack();
        Some(SchurForm { u, t })
    }

    /// `Z` with `AᵀZ + ZA + W = 0` ([`Side::Transposed`]) or `AZ + ZAᵀ + W = 0`
    /// ([`Side::Plain`]). Unique when no two eigenvalues of `A` sum to zero.
    pub fn continuous(&self, w: &DMatrix<f64>, side: Side) -> DMatrix<f64> {
        self.solve(w, side, Equation::Continuous)
    }

    /// `Z` with `Z = AᵀZA + W` ([`Side::Transposed`]) or `Z = AZAᵀ + W` ([`Side::Plain`]).
    /// Unique when no product of two eigenvalues of `A` is one.
    pub fn discrete(&self, w: &DMatrix<f64>, side: Side) -> DMatrix<f64> {
        self.solve(w, side, Equation::Discrete)
    }

    /// In Schur coordinates (`Ẑ = UᴴZU`, `Ŵ = UᴴWU`) with `M = Tᴴ` (lower triangular,
    /// [`Side::Transposed`]) or `M = T` (upper, [`Side::Plain`]) each column `j` of `Ẑ` solves
    /// a triangular system once the columns it couples to are known: with `s` the pivot
    /// (`t_jj` or its conjugate) and `v` the known columns' coupling (`Σ_{l<j} Ẑ_:l T_lj`, or
    /// `Σ_{l>j} Ẑ_:l conj(T_jl)`), `(M + sI)ẑ = −ŵ − v` (continuous) or
    /// `(I − sM)ẑ = ŵ + Mv` (discrete).
    fn solve(&self, w: &DMatrix<f64>, side: Side, equation: Equation) -> DMatrix<f64> {
        let n = self.t.nrows();
        let (u, t) = (&self.u, &self.t);
        let what = u.adjoint() * w.map(|v| Complex64::new(v, 0.0)) * u;
        let lower = side == Side::Transposed;
        // M (Tᴴ or T); the coupling coefficient of column l in column j (T_lj, or conj(T_jl))
        // is conj(M_jl) either way, the pivot s its diagonal's.
        let m = if lower { t.adjoint() } else { t.clone() };
        let zero = Complex64::new(0.0, 0.0);
        let one = Complex64::new(1.0, 0.0);
        let mut z = DMatrix::<Complex64>::zeros(n, n);
        let mut v = vec![zero; n];
        let mut rhs = vec![zero; n];
        for step in 0..n {
            let j = if lower { step } else { n - 1 - step };
            let s = m[(j, j)].conj();
            // The known columns' coupling: Σ_{l<j} Ẑ_:l T_lj, or Σ_{l>j} Ẑ_:l conj(T_jl).
            v.iter_mut().for_each(|x| *x = zero);
            let known = if lower { 0..j } else { j + 1..n };
            for l in known {
                let coefficient = m[(j, l)].conj();
                if coefficient != zero {
                    for (vk, zk) in v.iter_mut().zip(z.column(l).iter()) {
                        *vk += zk * coefficient;
                    }
                }
            }
            // (diag + scale·offdiag(M)) ẑ = rhs, substituted in M's direction.
            let (scale, diagonal): (Complex64, fn(Complex64, Complex64) -> Complex64) =
                match equation {
                    Equation::Continuous => {
                        for (i, r) in rhs.iter_mut().enumerate() {
                            *r = -what[(i, j)] - v[i];
                        }
                        (one, |mii, s| mii + s)
                    }
                    Equation::Discrete => {
                        let mv = &m * DVector::from_column_slice(&v);
                        for (i, r) in rhs.iter_mut().enumerate() {
                            *r = what[(i, j)] + mv[i];
                        }
                        (-s, |mii, s| 1.0 - s * mii)
                    }
                };
            for k in 0..n {
                let i = if lower { k } else { n - 1 - k };
                let off: Complex64 = if lower {
                    (0..i).map(|q| m[(i, q)] * z[(q, j)]).sum()
                } else {
                    (i + 1..n).map(|q| m[(i, q)] * z[(q, j)]).sum()
                };
                z[(i, j)] = (rhs[i] - scale * off) / diagonal(m[(i, i)], s);
            }
        }
        (u * z * u.adjoint()).map(|v| v.re)
    }
}

/// Which equation [`SchurForm::solve`] solves.
#[derive(Clone, Copy)]
enum Equation {
    Continuous,
    Discrete,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A nonnormal matrix with a complex pair, a real pole and a Jordan-like coupling; every
    /// equation's residual is at rounding level for symmetric and nonsymmetric right-hand sides.
    #[test]
    fn all_four_equations_hold_to_rounding() {
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                -0.3, 2.0, 0.5, 0.0, -2.0, -0.3, 1.0, 3.0, 0.0, 0.0, -1.5, 10.0, 0.0, 0.0, 0.0,
                -0.8,
            ],
        );
        let w = DMatrix::from_fn(4, 4, |i, j| 1.0 + (i * 3 + j * 7) as f64 % 5.0);
        let ws = (&w + w.transpose()) * 0.5;
        let s = SchurForm::new(&a).unwrap();
        let ad = &a * 0.3; // spectral radius < 1 for the discrete forms
        let sd = SchurForm::new(&ad).unwrap();
        for w in [&w, &ws] {
            let scale = w.norm();
            let z = s.continuous(w, Side::Transposed);
            assert!((a.transpose() * &z + &z * &a + w).norm() < 1e-13 * scale);
            let z = s.continuous(w, Side::Plain);
            assert!((&a * &z + &z * a.transpose() + w).norm() < 1e-13 * scale);
            let z = sd.discrete(w, Side::Transposed);
            assert!((ad.transpose() * &z * &ad + w - &z).norm() < 1e-13 * scale);
            let z = sd.discrete(w, Side::Plain);
            assert!((&ad * &z * ad.transpose() + w - &z).norm() < 1e-13 * scale);
        }
    }
}
