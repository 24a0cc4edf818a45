//! Model reduction by balanced truncation (square-root method) of stable discrete systems:
//! the Hankel singular values rank the states by how much they are both reached by the inputs
//! and seen at the outputs; truncating the small ones bounds the error,
//! `‖G − G_r‖_∞ ≤ 2 Σ σ_discarded`.

use crate::lyapunov::dlyap;
use crate::state_space::{LtiError, StateSpace};
use nalgebra::DMatrix;

/// A reduced model and what was discarded.
#[derive(Debug, Clone)]
pub struct Reduced {
    /// The reduced system (same inputs and outputs).
    pub sys: StateSpace,
    /// All Hankel singular values, descending.
    pub hankel: Vec<f64>,
    /// The a-priori H∞ error bound `2 Σ σ_i` over the discarded states.
    pub error_bound: f64,
}

/// A square root `R` with `P = Rᵀ R` of a symmetric positive semi-definite matrix, through
/// its eigen-decomposition (`R = Λ^½ Vᵀ`; eigenvalues below zero by rounding count as zero, so
/// it is robust to the near-singular gramians of lightly coupled states).
pub fn sqrt_factor(p: &DMatrix<f64>) -> DMatrix<f64> {
    let sym = (p + p.transpose()) * 0.5;
    let e = sym.symmetric_eigen();
    let d = DMatrix::from_diagonal(&e.eigenvalues.map(|l| l.max(0.0).sqrt()));
    d * e.eigenvectors.transpose()
}

/// The balancing of a stable discrete system, computed once (two gramians and an SVD) and
/// truncated to any order.
pub struct Balancing<'a> {
    sys: &'a StateSpace,
    /// `Wc = RᵀR`, `Wo = LᵀL`.
    r: DMatrix<f64>,
    l: DMatrix<f64>,
    u: DMatrix<f64>,
    vt: DMatrix<f64>,
    s: nalgebra::DVector<f64>,
    /// State indices by descending Hankel singular value.
    idx: Vec<usize>,
}

impl<'a> Balancing<'a> {
    /// Balances `sys`.
    pub fn new(sys: &'a StateSpace) -> Result<Self, LtiError> {
        let n = sys.nx();
        let (wc, _) = dlyap(&sys.a, &(&sys.b * sys.b.transpose()))?;
        let (wo, _) = dlyap(&sys.a.transpose(), &(sys.c.transpose() * &sys.c))?;
        let (r, l) = (sqrt_factor(&wc), sqrt_factor(&wo));
        let svd = (&l * r.transpose()).svd(true, true);
        let (u, vt, s) = (
            svd.u.expect("requested"),
            svd.v_t.expect("requested"),
            svd.singular_values,
        );
        let mut idx: Vec<usize> = (0..n).collect();
        idx.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
        Ok(Balancing {
            sys,
            r,
            l,
            u,
            vt,
            s,
            idx,
        })
    }

    /// States whose Hankel singular value exceeds `n·ε·σ_max`: the order of a minimal
    /// realisation as far as double precision can tell (the rest are neither reached nor seen).
    pub fn minimal_order(&self) -> usize {
        let n = self.sys.nx();
        let largest = self.s.iter().copied().fold(0.0, f64::max);
        let floor = largest * n as f64 * f64::EPSILON;
        self.s.iter().filter(|&&v| v > floor).count()
    }

    /// The reduced model of `order` states, at most [`Balancing::minimal_order`] of them (a
    /// state of zero Hankel singular value has no balanced coordinate: keeping it would divide
    /// by zero).
    pub fn truncate(&self, order: usize) -> Reduced {
        let (sys, n) = (self.sys, self.sys.nx());
        let order = order.min(self.minimal_order());
        let (r, l, u, vt, s) = (&self.r, &self.l, &self.u, &self.vt, &self.s);
        let hankel: Vec<f64> = self.idx.iter().map(|&i| s[i]).collect();
        let keep = &self.idx[..order];
        // T = Rᵀ V Σ^{-1/2}, T⁻¹ = Σ^{-1/2} Uᵀ L (kept columns / rows only).
        let t = DMatrix::from_fn(n, order, |i, k| {
            let j = keep[k];
            (0..n).map(|m| r[(m, i)] * vt[(j, m)]).sum::<f64>() / s[j].sqrt()
        });
        let ti = DMatrix::from_fn(order, n, |k, i| {
            let j = keep[k];
            (0..n).map(|m| u[(m, j)] * l[(m, i)]).sum::<f64>() / s[j].sqrt()
        });
        Reduced {
            sys: StateSpace {
                a: &ti * &sys.a * &t,
                b: &ti * &sys.b,
                c: &sys.c * &t,
                d: sys.d.clone(),
            },
            error_bound: 2.0 * hankel[order..].iter().sum::<f64>(),
            hankel,
        }
    }
}

/// Balanced truncation of a stable discrete `sys` to `order` states.
pub fn balanced_truncation(sys: &StateSpace, order: usize) -> Result<Reduced, LtiError> {
    Ok(Balancing::new(sys)?.truncate(order))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 6-state system of three well-separated modes: reduced to 2 states, the response error
    /// stays below the a-priori bound at every frequency, and keeping all states is exact.
    #[test]
    fn error_within_the_hankel_bound() {
        let blocks = [(0.95, 0.1), (0.6, 0.9), (0.2, 2.0)];
        let mut a = DMatrix::zeros(6, 6);
        for (k, &(r, th)) in blocks.iter().enumerate() {
            let (c, s) = (r * libm::cos(th), r * libm::sin(th));
            a[(2 * k, 2 * k)] = c;
            a[(2 * k, 2 * k + 1)] = -s;
            a[(2 * k + 1, 2 * k)] = s;
            a[(2 * k + 1, 2 * k + 1)] = c;
        }
        let b = DMatrix::from_column_slice(6, 1, &[1.0, 0.0, 0.3, 0.1, 0.05, 0.02]);
        let c = DMatrix::from_row_slice(1, 6, &[1.0, 0.5, 0.2, -0.1, 0.05, 0.01]);
        let sys = StateSpace {
            a,
            b,
            c,
            d: DMatrix::from_element(1, 1, 0.1),
        };
        let red = balanced_truncation(&sys, 2).unwrap();
        assert!(red.hankel.windows(2).all(|w| w[0] >= w[1]));
        let full = balanced_truncation(&sys, 6).unwrap();
        assert_eq!(full.sys.nx(), 6);
        for i in 0..200 {
            let f = i as f64 / 400.0; // cycles per sample
            let g = sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            let gr = red.sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            let gf = full.sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            assert!(
                (g - gr).norm() <= red.error_bound * (1.0 + 1e-9),
                "f {f}: {} > {}",
                (g - gr).norm(),
                red.error_bound
            );
            assert!((g - gf).norm() < 1e-9 * g.norm());
        }
    }

    /// A state neither reached nor seen (zero Hankel singular value) is dropped even when all
    /// states are asked for: the result is the minimal realisation, finite, with the same
    /// response — not NaN from dividing by √0.
    #[test]
    fn an_unreachable_state_is_dropped_not_divided_by_zero() {
        let a = DMatrix::from_row_slice(3, 3, &[0.9, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.3]);
        let b = DMatrix::from_column_slice(3, 1, &[1.0, 1.0, 0.0]);
        let c = DMatrix::from_row_slice(1, 3, &[1.0, 0.0, 1.0]);
        let sys = StateSpace {
            a,
            b,
            c,
            d: DMatrix::from_element(1, 1, 0.0),
        };
        let bal = Balancing::new(&sys).unwrap();
        // Only the 0.9 mode is both reached and seen.
        assert_eq!(bal.minimal_order(), 1);
        let red = bal.truncate(3);
        assert_eq!(red.sys.nx(), 1);
        assert!(red.sys.a.iter().all(|v| v.is_finite()));
        for f in [0.0, 0.1, 0.3] {
            let g = sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            let gr = red.sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            // 1/(z − 0.9) exactly.
            assert!((g - gr).norm() < 1e-12 * g.norm(), "f {f}");
        }
    }
}
