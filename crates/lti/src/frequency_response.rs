//! Frequency responses at many frequencies for the cost of one reduction (Laub 1981,
//! "Efficient multivariable frequency response computations", IEEE TAC 26(2); as SLICOT
//! `TB05AD`).
//!
//! `G(s) = C (sI − A)⁻¹ B + D` costs an `n × n` complex factorisation per frequency, O(n³).
//! With the system balanced (`TB01ID`, an exact diagonal scaling) and `A = Q H Qᵀ` (`H` upper
//! Hessenberg, `Q` orthogonal; once per system, O(n³) real), `(sI − A)⁻¹ = Q (sI − H)⁻¹ Qᵀ`,
//! and `sI − H` is solved by Gaussian elimination with partial pivoting between neighbouring
//! rows: O(n²) per frequency and input. The reduction's rounding is relative to ‖A‖, which in
//! a model whose states span many decades (metres beside volts, a 0.1 Hz noise filter beside a
//! 400 kHz current loop) can bury a small state; one step of iterative refinement against the
//! residual `B − (sI − A)X` of the balanced system itself — O(n²) again — restores the
//! accuracy of a direct solve (Skeel 1980: one step in working precision suffices).

use crate::state_space::{balance_system, LtiError, StateSpace};
use nalgebra::DMatrix;
use num_complex::Complex64 as C;

/// A system prepared for its frequency response at many frequencies (module docs).
#[derive(Debug, Clone)]
pub struct FrequencyResponse {
    /// States.
    n: usize,
    /// The balanced `A` (row-major), for the residual of the refinement.
    a: Vec<f64>,
    /// The balanced `B`, column by column (m columns of n).
    b: Vec<Vec<f64>>,
    /// `QᵀB`, column by column: the first solve's right-hand sides, once per system.
    qt_b: Vec<Vec<C>>,
    /// The balanced `C` (p × n, row-major).
    c: Vec<f64>,
    /// `D` (p × m).
    d: DMatrix<f64>,
    /// `Q` (row-major).
    q: Vec<f64>,
    /// `Qᵀ` (row-major).
    qt: Vec<f64>,
    /// `H = QᵀAQ`, upper Hessenberg, row-major.
    h: Vec<f64>,
}

impl FrequencyResponse {
    /// `sys` reduced once (its matrices in the model's units).
    pub fn new(sys: &StateSpace) -> Self {
        let n = sys.nx();
        let (a, b, c, _) = balance_system(sys.a.clone(), sys.b.clone(), sys.c.clone());
        let (q, h) = if n == 0 {
            (DMatrix::zeros(0, 0), DMatrix::zeros(0, 0))
        } else {
            a.clone().hessenberg().unpack()
        };
        let row_major = |m: &DMatrix<f64>| -> Vec<f64> { m.transpose().as_slice().to_vec() };
        let mut h = row_major(&h);
        for i in 0..n {
            for j in 0..i.saturating_sub(1) {
                h[i * n + j] = 0.0;
            }
        }
        let qt_b = (q.transpose() * &b)
            .column_iter()
            .map(|col| col.iter().map(|&v| C::new(v, 0.0)).collect())
            .collect();
        FrequencyResponse {
            n,
            qt_b,
            a: row_major(&a),
            b: b.column_iter()
                .map(|col| col.iter().copied().collect())
                .collect(),
            c: row_major(&c),
            d: sys.d.clone(),
            q: row_major(&q),
            qt: q.as_slice().to_vec(),
            h,
        }
    }

    /// `G(jω)` at `w_rad_s` (p × m); `Singular(w_rad_s)` on a pole at `jω`.
    pub fn continuous(&self, w_rad_s: f64) -> Result<DMatrix<C>, LtiError> {
        self.at(C::new(0.0, w_rad_s))
            .ok_or(LtiError::Singular(w_rad_s))
    }

    /// `G(z)` at `z = e^{j2πf·T}` of a sampled system with period `period_s` (p × m);
    /// `Singular(f_hz)` on a pole at that `z`.
    pub fn discrete(&self, f_hz: f64, period_s: f64) -> Result<DMatrix<C>, LtiError> {
        let z = C::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * period_s);
        self.at(z).ok_or(LtiError::Singular(f_hz))
    }

    /// `G(s)`, column by column (module docs); None when `sI − H` is singular.
    fn at(&self, s: C) -> Option<DMatrix<C>> {
        let n = self.n;
        let p = self.d.nrows();
        let factors = self.factor(s)?;
        let mut g = self.d.map(|v| C::new(v, 0.0));
        let mut residual = vec![C::new(0.0, 0.0); n];
        for (j, (b, qt_b)) in self.b.iter().zip(&self.qt_b).enumerate() {
            let mut x = self.solve(&factors, qt_b.clone());
            for (i, r) in residual.iter_mut().enumerate() {
                *r = b[i] - s * x[i] + dot(&self.a[i * n..(i + 1) * n], &x);
            }
            let qt_r = (0..n)
                .map(|i| dot(&self.qt[i * n..(i + 1) * n], &residual))
                .collect();
            for (xi, di) in x.iter_mut().zip(self.solve(&factors, qt_r)) {
                *xi += di;
            }
            for r in 0..p {
                g[(r, j)] += dot(&self.c[r * n..(r + 1) * n], &x);
            }
        }
        Some(g)
    }

    /// `sI − H` eliminated to upper-triangular form with partial pivoting between neighbouring
    /// rows: the triangle (row-major) and each column's swap and multiplier. None when singular.
    fn factor(&self, s: C) -> Option<Factors> {
        let n = self.n;
        let mut u: Vec<C> = self.h.iter().map(|&x| C::new(-x, 0.0)).collect();
        for i in 0..n {
            u[i * n + i] += s;
        }
        let mut steps = Vec::with_capacity(n.saturating_sub(1));
        for k in 0..n.saturating_sub(1) {
            let (top, bottom) = u.split_at_mut((k + 1) * n);
            let (row, next) = (&mut top[k * n..], &mut bottom[..n]);
            let swap = next[k].norm_sqr() > row[k].norm_sqr();
            if swap {
                row[k..].swap_with_slice(&mut next[k..]);
            }
            if row[k] == C::new(0.0, 0.0) {
                return None;
            }
            let l = next[k] / row[k];
            next[k] = C::new(0.0, 0.0);
            for (v, &above) in next[k + 1..].iter_mut().zip(&row[k + 1..]) {
                *v -= l * above;
            }
            steps.push((swap, l));
        }
        // The loop checked every pivot but the last.
        if n > 0 && u[n * n - 1] == C::new(0.0, 0.0) {
            return None;
        }
        Some(Factors { u, steps })
    }

    /// `(sI − A)⁻¹ r = Q (sI − H)⁻¹ y` for `y = Qᵀr`, with the factors of `sI − H`.
    fn solve(&self, f: &Factors, mut y: Vec<C>) -> Vec<C> {
        let n = self.n;
        for (k, &(swap, l)) in f.steps.iter().enumerate() {
            if swap {
                y.swap(k, k + 1);
            }
            let v = y[k];
            y[k + 1] -= l * v;
        }
        for i in (0..n).rev() {
            let row = &f.u[i * n..(i + 1) * n];
            let mut v = y[i];
            for (u, yk) in row[i + 1..].iter().zip(&y[i + 1..]) {
                v -= u * yk;
            }
            y[i] = v / row[i];
        }
        (0..n)
            .map(|i| dot(&self.q[i * n..(i + 1) * n], &y))
            .collect()
    }
}

impl StateSpace {
    /// `G(jω) = C (jωI − A)⁻¹ B + D` at `w_rad_s` (p × m complex). For many frequencies,
    /// prepare the system once with [`FrequencyResponse::new`].
    pub fn freq_response(&self, w_rad_s: f64) -> Result<DMatrix<C>, LtiError> {
        FrequencyResponse::new(self).continuous(w_rad_s)
    }

    /// Discrete-time `G(z) = C (zI − A)⁻¹ B + D` at `z = e^{j2πf·T}` (matrices of a sampled
    /// system with period `period_s`). For many frequencies, prepare the system once with
    /// [`FrequencyResponse::new`].
    pub fn freq_response_discrete(&self, f_hz: f64, period_s: f64) -> Result<DMatrix<C>, LtiError> {
        FrequencyResponse::new(self).discrete(f_hz, period_s)
    }
}

/// `Σ a_k x_k` of a real and a complex vector.
fn dot(a: &[f64], x: &[C]) -> C {
    let (mut re, mut im) = (0.0, 0.0);
    for (&a, x) in a.iter().zip(x) {
        re += a * x.re;
        im += a * x.im;
    }
    C::new(re, im)
}

/// The elimination of `sI − H` at one `s`.
struct Factors {
    /// The upper triangle (n × n, row-major).
    u: Vec<C>,
    /// Per column: whether its two rows were swapped, and the multiplier.
    steps: Vec<(bool, C)>,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dense direct solve `C (sI − A)⁻¹ B + D` (LU with partial pivoting), the reference.
    fn direct(sys: &StateSpace, s: C) -> DMatrix<C> {
        let n = sys.nx();
        let m = DMatrix::from_fn(n, n, |i, j| {
            let d = if i == j { s } else { C::new(0.0, 0.0) };
            d - sys.a[(i, j)]
        });
        let x = m.lu().solve(&sys.b.map(|v| C::new(v, 0.0))).unwrap();
        sys.c.map(|v| C::new(v, 0.0)) * x + sys.d.map(|v| C::new(v, 0.0))
    }

    /// A pseudo-random system with a spread of scales (fixed seed: a linear congruence).
    fn system(n: usize, m: usize, p: usize, seed: u64) -> StateSpace {
        let mut state = seed;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        };
        let a = DMatrix::from_fn(n, n, |i, j| next() * if i == j { 3.0 } else { 1.0 });
        StateSpace {
            a,
            b: DMatrix::from_fn(n, m, |_, _| next()),
            c: DMatrix::from_fn(p, n, |_, _| next()),
            d: DMatrix::from_fn(p, m, |_, _| next()),
        }
    }

    /// Against the dense solve on random MIMO systems, at frequencies on both sides of the
    /// poles: agreement to the conditioning of `sI − A` (both are backward stable).
    #[test]
    fn agrees_with_the_direct_solve() {
        for (seed, n) in [(1u64, 1usize), (2, 2), (3, 7), (4, 30), (5, 61)] {
            let sys = system(n, 3, 2, seed);
            let fr = FrequencyResponse::new(&sys);
            for w in [0.0, 1e-3, 0.37, 1.0, 2.9, 17.0, 1e4] {
                let s = C::new(0.0, w);
                let want = direct(&sys, s);
                let got = fr.continuous(w).unwrap();
                let scale = want.iter().map(|v| v.norm()).fold(1.0, f64::max);
                for (g, e) in got.iter().zip(want.iter()) {
                    assert!((g - e).norm() <= 1e-10 * scale, "n {n}, ω {w}: {g} vs {e}");
                }
            }
        }
    }

    /// First-order sections in closed form: `1/(s + a)` and its sampled pair `T/(z − p)`.
    #[test]
    fn first_order_closed_forms() {
        let sys = StateSpace {
            a: DMatrix::from_element(1, 1, -2.0),
            b: DMatrix::from_element(1, 1, 1.0),
            c: DMatrix::from_element(1, 1, 1.0),
            d: DMatrix::from_element(1, 1, 0.0),
        };
        let g = FrequencyResponse::new(&sys).continuous(3.0).unwrap()[(0, 0)];
        assert!((g - 1.0 / C::new(2.0, 3.0)).norm() < 1e-15);
        let t = 1e-3;
        let z = C::from_polar(1.0, 2.0 * std::f64::consts::PI * 50.0 * t);
        let mut d = sys.clone();
        d.a[(0, 0)] = 0.9;
        let g = FrequencyResponse::new(&d).discrete(50.0, t).unwrap()[(0, 0)];
        assert!((g - 1.0 / (z - 0.9)).norm() < 1e-14);
    }

    /// A pole exactly at the evaluated point is singular, not a number; a static gain has
    /// no states and is its `D`.
    #[test]
    fn singular_and_static_systems() {
        let integrator = StateSpace {
            a: DMatrix::zeros(1, 1),
            b: DMatrix::from_element(1, 1, 1.0),
            c: DMatrix::from_element(1, 1, 1.0),
            d: DMatrix::zeros(1, 1),
        };
        let fr = FrequencyResponse::new(&integrator);
        assert!(matches!(fr.continuous(0.0), Err(LtiError::Singular(_))));
        let gain = StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 1),
            c: DMatrix::zeros(1, 0),
            d: DMatrix::from_element(1, 1, 4.5),
        };
        assert_eq!(
            FrequencyResponse::new(&gain).continuous(1.0).unwrap()[(0, 0)],
            C::new(4.5, 0.0)
        );
    }
}
