//! Continuous LTI models in state space, their frequency response, the matrix exponential and
//! exact zero-order-hold discretisation — including a transport delay that is not a multiple of
//! the sample period (DESIGN.md, "Time and delay").

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
    /// use design::lti::StateSpace;
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
        const RADIX: f64 = 2.0;
        let n = self.nx();
        let mut scale = vec![1.0; n];
        loop {
            let mut converged = true;
            for (i, scale_i) in scale.iter_mut().enumerate() {
                let c: f64 = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| self.a[(j, i)].abs())
                    .sum();
                let r: f64 = (0..n)
                    .filter(|&j| j != i)
                    .map(|j| self.a[(i, j)].abs())
                    .sum();
                if c == 0.0 || r == 0.0 {
                    continue;
                }
                let total = c + r;
                let (mut f, mut cs) = (1.0, c);
                while cs < r / RADIX {
                    f *= RADIX;
                    cs *= RADIX * RADIX;
                }
                while cs >= r * RADIX {
                    f /= RADIX;
                    cs /= RADIX * RADIX;
                }
                if (cs + r) / f < 0.95 * total {
                    converged = false;
                    self.a.row_mut(i).scale_mut(1.0 / f);
                    self.a.column_mut(i).scale_mut(f);
                    self.b.row_mut(i).scale_mut(1.0 / f);
                    self.c.column_mut(i).scale_mut(f);
                    *scale_i *= f;
                }
            }
            if converged {
                return (self, scale);
            }
        }
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

    /// `G(jω) = C (jωI − A)⁻¹ B + D` at `w_rad_s` (p × m complex).
    pub fn freq_response(&self, w_rad_s: f64) -> Result<DMatrix<Complex64>, LtiError> {
        let n = self.nx();
        let jw_a = DMatrix::from_fn(n, n, |i, j| {
            let diag = if i == j {
                Complex64::new(0.0, w_rad_s)
            } else {
                Complex64::new(0.0, 0.0)
            };
            diag - self.a[(i, j)]
        });
        let b = self.b.map(|x| Complex64::new(x, 0.0));
        let x = jw_a.lu().solve(&b).ok_or(LtiError::Singular(w_rad_s))?;
        let c = self.c.map(|x| Complex64::new(x, 0.0));
        Ok(c * x + self.d.map(|x| Complex64::new(x, 0.0)))
    }

    /// Discrete-time `G(z) = C (zI − A)⁻¹ B + D` at `z = e^{j2πf·T}` (matrices of a sampled
    /// system with period `period_s`).
    pub fn freq_response_discrete(
        &self,
        f_hz: f64,
        period_s: f64,
    ) -> Result<DMatrix<Complex64>, LtiError> {
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * period_s);
        let n = self.nx();
        let za = DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                z - self.a[(i, j)]
            } else {
                Complex64::new(-self.a[(i, j)], 0.0)
            }
        });
        let b = self.b.map(|x| Complex64::new(x, 0.0));
        let x = za.lu().solve(&b).ok_or(LtiError::Singular(f_hz))?;
        Ok(self.c.map(|x| Complex64::new(x, 0.0)) * x + self.d.map(|x| Complex64::new(x, 0.0)))
    }

    /// Poles: [`eigenvalues`] of `A` (s-plane for continuous, z-plane for discrete models).
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

/// Eigenvalues of a real square matrix: Parlett–Reinsch balancing (an exact similarity), then
/// faer's Hessenberg–QR eigensolver. Balancing is essential for sampled closed loops whose
/// entries span 60 decades (volts, metres and controller states side by side): unbalanced, both
/// faer and nalgebra returned |z| ≈ 2 for a loop that runs stably (regression test below).
pub fn eigenvalues(a: &DMatrix<f64>) -> Vec<Complex64> {
    let n = a.nrows();
    let no_io = StateSpace {
        a: a.clone(),
        b: DMatrix::zeros(n, 0),
        c: DMatrix::zeros(0, n),
        d: DMatrix::zeros(0, 0),
    };
    let a = no_io.balanced().a;
    let m = faer::Mat::<f64>::from_fn(n, n, |i, j| a[(i, j)]);
    match m.eigenvalues() {
        Ok(v) => v.into_iter().map(|z| Complex64::new(z.re, z.im)).collect(),
        Err(_) => vec![Complex64::new(f64::NAN, f64::NAN); n],
    }
}

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

/// Matrix exponential `e^A` by scaling and squaring with the degree-13 Padé approximant
/// (Higham 2005, "The scaling and squaring method for the matrix exponential revisited").
pub fn expm(a: &DMatrix<f64>) -> DMatrix<f64> {
    const B: [f64; 14] = [
        64764752532480000.0,
        32382376266240000.0,
        7771770303897600.0,
        1187353796428800.0,
        129060195264000.0,
        10559470521600.0,
        670442572800.0,
        33522128640.0,
        1323241920.0,
        40840800.0,
        960960.0,
        16380.0,
        182.0,
        1.0,
    ];
    const THETA13: f64 = 5.371920351148152;
    let n = a.nrows();
    let norm1 = (0..n).map(|j| a.column(j).abs().sum()).fold(0.0, f64::max);
    let s = if norm1 > THETA13 {
        (norm1 / THETA13).log2().ceil() as i32
    } else {
        0
    };
    let a = a / 2f64.powi(s);
    let id = DMatrix::<f64>::identity(n, n);
    let a2 = &a * &a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let u_inner = &a6 * (&a6 * B[13] + &a4 * B[11] + &a2 * B[9])
        + &a6 * B[7]
        + &a4 * B[5]
        + &a2 * B[3]
        + &id * B[1];
    let u = &a * u_inner;
    let v = &a6 * (&a6 * B[12] + &a4 * B[10] + &a2 * B[8])
        + &a6 * B[6]
        + &a4 * B[4]
        + &a2 * B[2]
        + &id * B[0];
    let mut r = (&v - &u)
        .lu()
        .solve(&(&v + &u))
        .expect("Padé denominator is nonsingular for ‖A‖ ≤ θ13");
    for _ in 0..s {
        r = &r * &r;
    }
    r
}

/// Tustin (bilinear) discretisation at period `period_s`, pre-warped at `prewarp_hz` if given:
/// `H_d(e^{jωT}) = H(jK·tan(ωT/2))` with `K = 2/T`, or `K = ω0/tan(ω0T/2)` so the responses
/// agree exactly at `f0`.
pub fn c2d_tustin(
    sys: &StateSpace,
    period_s: f64,
    prewarp_hz: Option<f64>,
) -> Result<StateSpace, LtiError> {
    let k = match prewarp_hz {
        Some(f0) => {
            let w0 = 2.0 * std::f64::consts::PI * f0;
            w0 / (w0 * period_s / 2.0).tan()
        }
        None => 2.0 / period_s,
    };
    let h = 2.0 / k; // the equivalent step
    let n = sys.nx();
    let id = DMatrix::<f64>::identity(n, n);
    let m = (&id - &sys.a * (h / 2.0))
        .try_inverse()
        .ok_or(LtiError::Argument("c2d_tustin: I − A·T/2 is singular"))?;
    Ok(StateSpace {
        a: &m * (&id + &sys.a * (h / 2.0)),
        b: &m * &sys.b * h,
        c: &sys.c * &m,
        d: &sys.d + &sys.c * &m * &sys.b * (h / 2.0),
    })
}

/// `(e^{A h}, ∫₀ʰ e^{A s} ds · B)`: the exact response over `h` seconds to an input held
/// constant, from one exponential of the block matrix `[[A, B], [0, 0]]·h`.
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut big = DMatrix::<f64>::zeros(n + m, n + m);
    big.view_mut((0, 0), (n, n)).copy_from(&(a * h));
    big.view_mut((0, n), (n, m)).copy_from(&(b * h));
    let e = expm(&big);
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

/// Exact discretisation over one period `T` of an input that switches inside the period: the
/// previous sample's value acts for the first `delay_s`, the new one for the rest.
///
/// `x[k+1] = phi·x[k] + gamma_prev·u[k−1] + gamma_now·u[k]`
#[derive(Debug, Clone, PartialEq)]
pub struct DelayedZoh {
    /// `e^{A T}`.
    pub phi: DMatrix<f64>,
    /// Effect of the input held from the previous tick (acts for `delay_s`).
    pub gamma_prev: DMatrix<f64>,
    /// Effect of this tick's input (acts for `T − delay_s`).
    pub gamma_now: DMatrix<f64>,
}

impl DelayedZoh {
    /// Discretises `(a, b)` at `period_s` with the input arriving `delay_s` ∈ [0, period_s]
    /// after the tick (a delay longer than a period is handled by delaying whole samples first).
    pub fn new(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        period_s: f64,
        delay_s: f64,
    ) -> Result<Self, LtiError> {
        if !(period_s > 0.0 && period_s.is_finite()) {
            return Err(LtiError::Argument("period_s must be finite and > 0"));
        }
        if !(0.0..=period_s).contains(&delay_s) {
            return Err(LtiError::Argument("delay_s must lie in [0, period_s]"));
        }
        let (phi_late, gamma_now) = zoh(a, b, period_s - delay_s);
        let (phi_early, gamma_early) = zoh(a, b, delay_s);
        Ok(DelayedZoh {
            phi: &phi_late * phi_early,
            gamma_prev: &phi_late * gamma_early,
            gamma_now,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// e^{At} of a damped oscillator against its closed form. Each squaring step can double the
    /// rounding error, so the bound is 1e-13·2^s relative (s = squarings, 13 at t = 3 s).
    #[test]
    fn expm_of_damped_oscillator_matches_closed_form() {
        let (wn, zeta) = (2.0 * PI * 82.0, 0.01);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * zeta * wn]);
        for t in [1e-6, 5e-6, 1e-3, 0.1, 3.0] {
            let e = expm(&(&a * t));
            let wd = wn * (1.0 - zeta * zeta).sqrt();
            let (s, c, ex) = ((wd * t).sin(), (wd * t).cos(), (-zeta * wn * t).exp());
            let want = [
                ex * (c + zeta * wn / wd * s),
                ex * s / wd,
                -ex * wn * wn / wd * s,
                ex * (c - zeta * wn / wd * s),
            ];
            let got = [e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]];
            let norm1 = (&a * t).abs().row_sum().max(); // ‖At‖₁: largest column sum
            let squarings = (norm1 / 5.37).log2().ceil().max(0.0);
            // Entries differ in scale by ωn²: compare each against its own natural scale.
            let natural = [1.0, 1.0 / wd, wn * wn / wd, 1.0];
            for ((g, w), s) in got.iter().zip(want).zip(natural) {
                let tol = 1e-13 * 2f64.powf(squarings) * s;
                assert!((g - w).abs() < tol, "t={t}: {g} vs {w}");
            }
        }
    }

    /// A pure integrator ẋ = u: Φ = 1, Γ = h; with a delay d the held old input acts for d.
    #[test]
    fn delayed_zoh_of_integrator() {
        let a = DMatrix::from_element(1, 1, 0.0);
        let b = DMatrix::from_element(1, 1, 1.0);
        let z = DelayedZoh::new(&a, &b, 5e-6, 3.159e-6).unwrap();
        assert!((z.phi[(0, 0)] - 1.0).abs() < 1e-15);
        assert!((z.gamma_prev[(0, 0)] - 3.159e-6).abs() < 1e-18);
        assert!((z.gamma_now[(0, 0)] - (5e-6 - 3.159e-6)).abs() < 1e-18);
    }

    /// First-order lag ẋ = −a x + a u: the delayed ZOH terms have closed forms.
    #[test]
    fn delayed_zoh_of_first_order_lag() {
        let p = 2.0 * PI * 10e3;
        let (t, d) = (1.0 / 199_600.0, 3.159e-6);
        let z = DelayedZoh::new(
            &DMatrix::from_element(1, 1, -p),
            &DMatrix::from_element(1, 1, p),
            t,
            d,
        )
        .unwrap();
        let phi = (-p * t).exp();
        let now = 1.0 - (-p * (t - d)).exp();
        let prev = (-p * (t - d)).exp() * (1.0 - (-p * d).exp());
        assert!((z.phi[(0, 0)] - phi).abs() < 1e-14);
        assert!((z.gamma_now[(0, 0)] - now).abs() < 1e-14);
        assert!((z.gamma_prev[(0, 0)] - prev).abs() < 1e-14);
    }

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
        let want =
            1.0 - (-z * w * t).exp() * ((wd * t).cos() + z / (1.0 - z * z).sqrt() * (wd * t).sin());
        assert!((y - want).abs() < 1e-12, "{y} vs {want}");
        assert!(phi.iter().all(|x| x.is_finite()));
    }

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
        let a = (-2.0 * PI * 0.1 / 199_600.0f64).exp();
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

    /// c2d by ZOH of a mass-spring-damper puts its poles at e^{sT} (the known discrete poles).
    #[test]
    fn zoh_poles_of_mass_spring_damper() {
        let (m, c, k) = (0.175, 2.28, 21965.0);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -k / m, -c / m]);
        let t = 1.0 / 20_000.0;
        let (phi, _) = zoh(&a, &DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / m]), t);
        let zeta = c / (2.0 * (k * m).sqrt());
        let wn = (k / m).sqrt();
        let s = Complex64::new(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt());
        let want = (s * t).exp();
        let disc = StateSpace::new(
            phi,
            DMatrix::zeros(2, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let got = disc.poles().into_iter().find(|p| p.im > 0.0).unwrap();
        assert!((got - want).norm() < 1e-12, "{got} vs {want}");
    }

    /// Tustin maps H(s) to H_d(z) exactly along the warped frequency axis; pre-warped, exactly
    /// at f0 too.
    #[test]
    fn tustin_frequency_mapping() {
        let (m, c, k) = (0.175, 2.28, 21965.0);
        let sys = StateSpace::new(
            DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -k / m, -c / m]),
            DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / m]),
            DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let t = 1.0 / 20_000.0;
        for pre in [None, Some(56.4)] {
            let d = c2d_tustin(&sys, t, pre).unwrap();
            let kk = pre.map_or(2.0 / t, |f0: f64| 2.0 * PI * f0 / (PI * f0 * t).tan());
            for f in [1.0, 56.4, 300.0, 3000.0, 9000.0] {
                let w_analog = kk * (PI * f * t).tan();
                let want = sys.freq_response(w_analog).unwrap()[(0, 0)];
                let got = d.freq_response_discrete(f, t).unwrap()[(0, 0)];
                // Near Nyquist the response is ~100 dB below DC and forms by cancellation
                // between the feed-through and state terms: 1e-9 relative is the precision.
                assert!(
                    (got - want).norm() < 1e-9 * want.norm(),
                    "{pre:?} {f}: rel {:e}",
                    (got - want).norm() / want.norm()
                );
            }
            if let Some(f0) = pre {
                let exact = sys.freq_response_at(f0, 0, 0).unwrap();
                let got = d.freq_response_discrete(f0, t).unwrap()[(0, 0)];
                assert!((got - exact).norm() < 1e-10 * exact.norm());
            }
        }
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
