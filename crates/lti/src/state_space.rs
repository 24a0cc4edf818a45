//! Continuous LTI models in state space: shapes, frequency responses, balancing, realisations
//! of rational functions, and eigenvalues.

use nalgebra::DMatrix;
use num_complex::Complex64;

/// Shape or value errors of LTI models.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LtiError {
    /// Matrix dimensions do not fit together.
    #[error("matrix `{matrix}` is {rows}×{cols}, expected {want_rows}×{want_cols}")]
    Shape {
        /// Which matrix.
        matrix: &'static str,
        /// Its rows.
        rows: usize,
        /// Its columns.
        cols: usize,
        /// Expected rows.
        want_rows: usize,
        /// Expected columns.
        want_cols: usize,
    },
    /// `jωI − A` is singular at this frequency (a pole on the imaginary axis), ω in rad/s.
    #[error("the model has a pole at jω = j{0} rad/s")]
    Singular(f64),
    /// A time or delay argument is out of range.
    #[error("{0}")]
    Argument(&'static str),
}

/// `ẋ = A x + B u`, `y = C x + D u` (units are the model's).
#[derive(Debug, Clone, PartialEq)]
pub struct StateSpace {
    /// State matrix (n × n).
    pub a: DMatrix<f64>,
    /// Input matrix (n × m).
    pub b: DMatrix<f64>,
    /// Output matrix (p × n).
    pub c: DMatrix<f64>,
    /// Feed-through matrix (p × m).
    pub d: DMatrix<f64>,
}

fn check(matrix: &'static str, m: &DMatrix<f64>, rows: usize, cols: usize) -> Result<(), LtiError> {
    if m.nrows() == rows && m.ncols() == cols {
        Ok(())
    } else {
        Err(LtiError::Shape {
            matrix,
            rows: m.nrows(),
            cols: m.ncols(),
            want_rows: rows,
            want_cols: cols,
        })
    }
}

impl StateSpace {
    /// A model from its four matrices, with the shapes checked.
    pub fn new(
        a: DMatrix<f64>,
        b: DMatrix<f64>,
        c: DMatrix<f64>,
        d: DMatrix<f64>,
    ) -> Result<Self, LtiError> {
        let (n, m, p) = (a.nrows(), b.ncols(), c.nrows());
        check("a", &a, n, n)?;
        check("b", &b, n, m)?;
        check("c", &c, p, n)?;
        check("d", &d, p, m)?;
        Ok(StateSpace { a, b, c, d })
    }

    /// A realisation (controllable canonical form) of `num(s)/den(s)`, coefficients in
    /// descending powers of `s`; requires `deg num ≤ deg den` and `den[0] ≠ 0`.
    ///
    /// ```
    /// use lti::StateSpace;
    /// let lag = StateSpace::from_tf(&[100.0], &[1.0, 100.0]).unwrap(); // 100/(s + 100)
    /// assert!((lag.freq_response_at(0.0, 0, 0).unwrap().re - 1.0).abs() < 1e-15);
    /// ```
    pub fn from_tf(num: &[f64], den: &[f64]) -> Result<Self, LtiError> {
        let lead = *den.first().ok_or(LtiError::Argument("empty denominator"))?;
        if lead == 0.0 || num.len() > den.len() {
            return Err(LtiError::Argument(
                "from_tf needs den[0] ≠ 0 and deg num ≤ deg den",
            ));
        }
        let n = den.len() - 1;
        let a_coef: Vec<f64> = den[1..].iter().map(|x| x / lead).collect();
        let mut b_coef = vec![0.0; n + 1 - num.len()];
        b_coef.extend(num.iter().map(|x| x / lead));
        let b0 = b_coef[0];
        let a = DMatrix::from_fn(n, n, |i, j| {
            if i == 0 {
                -a_coef[j]
            } else if i == j + 1 {
                1.0
            } else {
                0.0
            }
        });
        let b = DMatrix::from_fn(n, 1, |i, _| if i == 0 { 1.0 } else { 0.0 });
        let c = DMatrix::from_fn(1, n, |_, j| b_coef[j + 1] - a_coef[j] * b0);
        Ok(StateSpace::new(a, b, c, DMatrix::from_element(1, 1, b0))?.balanced())
    }

    /// The same system under a diagonal similarity `x = D·x̃` (powers of 2, so exact) that
    /// makes the rows and columns of `A` comparable in norm (Parlett–Reinsch, as LAPACK
    /// `dgebal` without permutations). Companion forms of fast poles span 12+ decades; balanced,
    /// the matrix exponential and eigenvalues keep their accuracy.
    pub fn balanced(self) -> StateSpace {
        self.balance().0
    }

    /// [`StateSpace::balanced`] and the scaling `D` (diagonal), so `x_original[i] = D[i]·x̃[i]`.
    pub fn balance(mut self) -> (StateSpace, Vec<f64>) {
        let (a, scale) = balance(self.a);
        self.a = a;
        for (i, d) in scale.iter().enumerate() {
            self.b.row_mut(i).scale_mut(1.0 / d);
            self.c.column_mut(i).scale_mut(*d);
        }
        (self, scale)
    }

    /// `next ∘ self`: the output of `self` drives `next` (`ny(self) = nu(next)`).
    pub fn series(&self, next: &StateSpace) -> Result<StateSpace, LtiError> {
        check("next.b", &next.b, next.nx(), self.ny())?;
        let (n1, n2) = (self.nx(), next.nx());
        let mut a = DMatrix::zeros(n1 + n2, n1 + n2);
        a.view_mut((0, 0), (n1, n1)).copy_from(&self.a);
        a.view_mut((n1, 0), (n2, n1))
            .copy_from(&(&next.b * &self.c));
        a.view_mut((n1, n1), (n2, n2)).copy_from(&next.a);
        let mut b = DMatrix::zeros(n1 + n2, self.nu());
        b.view_mut((0, 0), (n1, self.nu())).copy_from(&self.b);
        b.view_mut((n1, 0), (n2, self.nu()))
            .copy_from(&(&next.b * &self.d));
        let mut c = DMatrix::zeros(next.ny(), n1 + n2);
        c.view_mut((0, 0), (next.ny(), n1))
            .copy_from(&(&next.d * &self.c));
        c.view_mut((0, n1), (next.ny(), n2)).copy_from(&next.c);
        StateSpace::new(a, b, c, &next.d * &self.d)
    }

    /// The same model scaled at the output by `k`.
    pub fn scaled(mut self, k: f64) -> StateSpace {
        self.c *= k;
        self.d *= k;
        self
    }

    /// Number of states.
    pub fn nx(&self) -> usize {
        self.a.nrows()
    }

    /// Number of inputs.
    pub fn nu(&self) -> usize {
        self.b.ncols()
    }

    /// Number of outputs.
    pub fn ny(&self) -> usize {
        self.c.nrows()
    }

    /// Poles: [`eigenvalues`] of `A` (s-plane for continuous, z-plane for discrete models).
    #[cfg(feature = "solvers")]
    pub fn poles(&self) -> Vec<Complex64> {
        eigenvalues(&self.a)
    }

    /// The single entry `(output, input)` of [`StateSpace::freq_response`] at `f_hz`.
    pub fn freq_response_at(
        &self,
        f_hz: f64,
        output: usize,
        input: usize,
    ) -> Result<Complex64, LtiError> {
        Ok(self.freq_response(2.0 * std::f64::consts::PI * f_hz)?[(output, input)])
    }
}

/// The diagonal similarity `D⁻¹AD` (powers of 2, so exact) that makes the rows and columns of
/// `a` comparable in norm (Parlett–Reinsch, as LAPACK `dgebal` without permutations), and `D`.
pub fn balance(a: DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let n = a.nrows();
    let (a, _, _, scale) = balance_system(a, DMatrix::zeros(n, 0), DMatrix::zeros(0, n));
    (a, scale)
}

/// [`balance`] of the system matrix `[A B; C 0]` by a state scaling alone (as SLICOT `TB01ID`):
/// each state's row of `[A B]` and column of `[A; C]` made comparable in norm. Returns
/// `D⁻¹AD`, `D⁻¹B`, `CD` and `D`.
pub fn balance_system(
    mut a: DMatrix<f64>,
    mut b: DMatrix<f64>,
    mut c: DMatrix<f64>,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>, Vec<f64>) {
    const RADIX: f64 = 2.0;
    let n = a.nrows();
    let mut scale = vec![1.0; n];
    let sum = |v: &mut dyn Iterator<Item = f64>| v.map(f64::abs).sum::<f64>();
    loop {
        let mut converged = true;
        for (i, scale_i) in scale.iter_mut().enumerate() {
            let col = sum(&mut (0..n).filter(|&j| j != i).map(|j| a[(j, i)]))
                + sum(&mut c.column(i).iter().copied());
            let row = sum(&mut (0..n).filter(|&j| j != i).map(|j| a[(i, j)]))
                + sum(&mut b.row(i).iter().copied());
            if col == 0.0 || row == 0.0 {
                continue;
            }
            let total = col + row;
            let (mut f, mut cs) = (1.0, col);
            while cs < row / RADIX {
                f *= RADIX;
                cs *= RADIX * RADIX;
            }
            while cs >= row * RADIX {
                f /= RADIX;
                cs /= RADIX * RADIX;
            }
            if (cs + row) / f < 0.95 * total {
                converged = false;
                a.row_mut(i).scale_mut(1.0 / f);
                b.row_mut(i).scale_mut(1.0 / f);
                a.column_mut(i).scale_mut(f);
                c.column_mut(i).scale_mut(f);
                *scale_i *= f;
            }
        }
        if converged {
            return (a, b, c, scale);
        }
    }
}

/// Eigenvalues of a real square matrix: Parlett–Reinsch balancing (an exact similarity), then
/// faer's Hessenberg–QR eigensolver. Balancing is essential for sampled closed loops whose
/// entries span 60 decades (volts, metres and controller states side by side): unbalanced, both
/// faer and nalgebra returned |z| ≈ 2 for a loop that runs stably (regression test below).
#[cfg(feature = "solvers")]
pub fn eigenvalues(a: &DMatrix<f64>) -> Vec<Complex64> {
    let n = a.nrows();
    let (a, _) = balance(a.clone());
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
    let (mut re, mut im) = (
        faer::diag::Diag::<f64>::zeros(n),
        faer::diag::Diag::<f64>::zeros(n),
    );
    // Sequential: at the orders a controller has, threads cost more than they save (a
    // Riccati solve of order 80 spent a sixth of its time handing this to rayon's pool).
    let (par, params) = (faer::Par::Seq, Default::default());
    let no = faer::linalg::evd::ComputeEigenvectors::No;
    let mut memory = faer::dyn_stack::MemBuffer::new(faer::linalg::evd::evd_scratch::<f64>(
        n, no, no, par, params,
    ));
    let stack = faer::dyn_stack::MemStack::new(&mut memory);
    match faer::linalg::evd::evd_real(
        m.as_ref(),
        re.as_mut(),
        im.as_mut(),
        None,
        None,
        par,
        stack,
        params,
    ) {
        Ok(()) => (0..n).map(|i| Complex64::new(re[i], im[i])).collect(),
        Err(_) => vec![Complex64::new(f64::NAN, f64::NAN); n],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::discretise::zoh;
    use std::f64::consts::PI;

    #[test]
    fn freq_response_of_mass_spring() {
        // x/F = 1/(m s² + c s + k)
        let (m, c, k) = (0.175, 2.28, 21965.0);
        let ss = StateSpace::new(
            DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -k / m, -c / m]),
            DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / m]),
            DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        for f in [1.0, 56.0, 1e3, 1e5] {
            let w = 2.0 * PI * f;
            let want = Complex64::new(1.0, 0.0) / Complex64::new(k - m * w * w, c * w);
            let got = ss.freq_response_at(f, 0, 0).unwrap();
            assert!((got - want).norm() < 1e-12 * want.norm());
        }
    }

    #[test]
    fn from_tf_realises_the_rational_function() {
        // (2s² + 3s + 5)/(s³ + 4s² + 6s + 8)
        let ss = StateSpace::from_tf(&[2.0, 3.0, 5.0], &[1.0, 4.0, 6.0, 8.0]).unwrap();
        // Biproper: (s + 1)/(0.5 s + 2)
        let bi = StateSpace::from_tf(&[1.0, 1.0], &[0.5, 2.0]).unwrap();
        for f in [0.0, 0.3, 1.0, 10.0] {
            let s = Complex64::new(0.0, 2.0 * PI * f);
            let want = (2.0 * s * s + 3.0 * s + 5.0) / (s * s * s + 4.0 * s * s + 6.0 * s + 8.0);
            assert!((ss.freq_response_at(f, 0, 0).unwrap() - want).norm() < 1e-13);
            let want = (s + 1.0) / (0.5 * s + 2.0);
            assert!((bi.freq_response_at(f, 0, 0).unwrap() - want).norm() < 1e-13);
        }
        assert!(StateSpace::from_tf(&[1.0, 0.0, 0.0], &[1.0, 1.0]).is_err());
        // Series is the product of the two responses.
        let prod = ss.series(&bi).unwrap();
        for f in [0.0, 0.7, 5.0] {
            let want =
                ss.freq_response_at(f, 0, 0).unwrap() * bi.freq_response_at(f, 0, 0).unwrap();
            assert!((prod.freq_response_at(f, 0, 0).unwrap() - want).norm() < 1e-13);
        }
    }

    /// A 400 kHz second-order section: balancing evens out the companion form and keeps the
    /// response, and the ZOH of the balanced form matches the analytic step response.
    #[test]
    fn balancing_keeps_the_response_and_fixes_the_exponential() {
        let (w, z) = (2.0 * PI * 400e3, 0.707);
        let raw = StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[-2.0 * z * w, -w * w, 1.0, 0.0]),
            b: DMatrix::from_row_slice(2, 1, &[1.0, 0.0]),
            c: DMatrix::from_row_slice(1, 2, &[0.0, w * w]),
            d: DMatrix::zeros(1, 1),
        };
        let bal = raw.clone().balanced();
        let spread = |m: &DMatrix<f64>| {
            let nz: Vec<f64> = m.iter().filter(|x| **x != 0.0).map(|x| x.abs()).collect();
            nz.iter().cloned().fold(0.0, f64::max) / nz.iter().cloned().fold(f64::MAX, f64::min)
        };
        assert!(spread(&bal.a) < 1e3 && spread(&raw.a) > 1e10);
        for f in [1e3, 4e5, 3e6] {
            let d = raw.freq_response_at(f, 0, 0).unwrap() - bal.freq_response_at(f, 0, 0).unwrap();
            assert!(d.norm() < 1e-12);
        }
        let t = 1.841e-6;
        let (phi, gam) = zoh(&bal.a, &bal.b, t);
        let y = (&bal.c * gam)[(0, 0)];
        let wd = w * (1.0 - z * z).sqrt();
        let want = 1.0
            - libm::exp(-z * w * t)
                * (libm::cos(wd * t) + z / (1.0 - z * z).sqrt() * libm::sin(wd * t));
        assert!((y - want).abs() < 1e-12, "{y} vs {want}");
        assert!(phi.iter().all(|x| x.is_finite()));
    }

    /// A stable matrix whose entries span 1e-40 … 1e13 through a diagonal similarity: the
    /// eigenvalues are those of the well-scaled original.
    #[test]
    fn eigenvalues_of_a_badly_scaled_matrix() {
        let base = DMatrix::from_row_slice(3, 3, &[0.5, 0.3, 0.0, -0.2, 0.6, 0.1, 0.0, 0.4, -0.3]);
        let d = [1e-20, 1.0, 1e13];
        let scaled = DMatrix::from_fn(3, 3, |i, j| base[(i, j)] * d[i] / d[j]);
        let mut want: Vec<f64> = eigenvalues(&base).iter().map(|z| z.norm()).collect();
        let mut got: Vec<f64> = eigenvalues(&scaled).iter().map(|z| z.norm()).collect();
        want.sort_by(f64::total_cmp);
        got.sort_by(f64::total_cmp);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).abs() < 1e-12, "{got:?} vs {want:?}");
        }
    }

    #[test]
    fn shape_errors_name_the_matrix() {
        let e = StateSpace::new(
            DMatrix::zeros(2, 2),
            DMatrix::zeros(3, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(1, 1),
        );
        assert!(matches!(e, Err(LtiError::Shape { matrix: "b", .. })));
    }
}
