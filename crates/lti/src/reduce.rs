//! Model reduction by balanced truncation (square-root method) of stable discrete systems:
//! the Hankel singular values rank the states by how much they are both reached by the inputs
//! and seen at the outputs; truncating the small ones bounds the error,
//! `‖G − G_r‖_∞ ≤ 2 Σ σ_discarded`.

use crate::lyapunov::dlyap;
use crate::square_root::sqrt_factor;
use crate::state_space::{balance_system, LtiError, StateSpace};
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

/// The balancing of a stable discrete system, computed once (two gramians and an SVD) and
/// truncated to any order.
pub struct Balancing {
    /// The system balanced: a single-input or single-output one with the states its input
    /// does not reach or its output does not see removed first ([`reachable_part`]).
    sys: StateSpace,
    /// `Wc = RᵀR`, `Wo = LᵀL`.
    r: DMatrix<f64>,
    l: DMatrix<f64>,
    u: DMatrix<f64>,
    vt: DMatrix<f64>,
    s: nalgebra::DVector<f64>,
    /// State indices by descending Hankel singular value.
    idx: Vec<usize>,
}

impl Balancing {
    /// Balances `sys`. A single input's unreached states and a single output's unseen ones are
    /// removed first, exactly ([`reachable_part`]): their gramian direction is zero in one
    /// gramian but can dominate the other — a slow disturbance state the output sees, 10⁵
    /// times the rest — whose other directions are then known only to `ε·‖W‖`, and the
    /// truncation built on them misses the system by O(1).
    pub fn new(sys: &StateSpace) -> Result<Self, LtiError> {
        let (a, b, c, _) = balance_system(sys.a.clone(), sys.b.clone(), sys.c.clone());
        let mut sys = StateSpace {
            a,
            b,
            c,
            d: sys.d.clone(),
        };
        if sys.nu() == 1 {
            sys = reachable_part(&sys);
        }
        if sys.ny() == 1 {
            sys = dual(&reachable_part(&dual(&sys)));
        }
        let n = sys.nx();
        if n == 0 {
            return Ok(Balancing {
                sys,
                r: DMatrix::zeros(0, 0),
                l: DMatrix::zeros(0, 0),
                u: DMatrix::zeros(0, 0),
                vt: DMatrix::zeros(0, 0),
                s: nalgebra::DVector::zeros(0),
                idx: Vec::new(),
            });
        }
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
        let (sys, n) = (&self.sys, self.sys.nx());
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

/// The part of the single-input `sys` its input reaches, by the orthogonal controllability
/// staircase: a reflection takes `b` to `β·e₁`, then the Hessenberg reduction of `A` (which
/// keeps `e₁`) puts the reached states first; those after the first subdiagonal entry below
/// `n·ε·‖A‖_F` are not reached and are dropped. Orthogonal transformations only: the response
/// is unchanged to rounding.
fn reachable_part(sys: &StateSpace) -> StateSpace {
    let n = sys.nx();
    let beta = sys.b.norm();
    if n == 0 || beta == 0.0 {
        return StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, sys.nu()),
            c: DMatrix::zeros(sys.ny(), 0),
            d: sys.d.clone(),
        };
    }
    let mut v = sys.b.column(0).clone_owned();
    v[0] += beta.copysign(v[0]);
    let reflection =
        DMatrix::<f64>::identity(n, n) - (&v * v.transpose()) * (2.0 / v.norm_squared());
    let (q, h) = (&reflection * &sys.a * &reflection).hessenberg().unpack();
    let t = reflection * q;
    let negligible = n as f64 * f64::EPSILON * sys.a.norm();
    let k = (0..n - 1)
        .find(|&k| h[(k + 1, k)].abs() <= negligible)
        .map_or(n, |k| k + 1);
    StateSpace {
        a: h.view((0, 0), (k, k)).into_owned(),
        b: (t.transpose() * &sys.b).rows(0, k).into_owned(),
        c: (&sys.c * &t).columns(0, k).into_owned(),
        d: sys.d.clone(),
    }
}

/// The dual system `(Aᵀ, Cᵀ, Bᵀ, Dᵀ)`.
fn dual(sys: &StateSpace) -> StateSpace {
    StateSpace {
        a: sys.a.transpose(),
        b: sys.c.transpose(),
        c: sys.b.transpose(),
        d: sys.d.transpose(),
    }
}

/// Balanced truncation of a stable discrete `sys` to `order` states.
pub fn balanced_truncation(sys: &StateSpace, order: usize) -> Result<Reduced, LtiError> {
    Ok(Balancing::new(sys)?.truncate(order))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `n`×`n` matrix (n ≥ 6) whose first six states are three well-separated discrete
    /// modes (radius, angle per tick: 0.95, 0.1; 0.6, 0.9; 0.2, 2.0), the rest zero.
    fn three_modes(n: usize) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(n, n);
        for (k, &(r, th)) in [(0.95, 0.1), (0.6, 0.9), (0.2, 2.0)].iter().enumerate() {
            let (c, s) = (r * libm::cos(th), r * libm::sin(th));
            a[(2 * k, 2 * k)] = c;
            a[(2 * k, 2 * k + 1)] = -s;
            a[(2 * k + 1, 2 * k)] = s;
            a[(2 * k + 1, 2 * k + 1)] = c;
        }
        a
    }

    /// A 6-state system of three well-separated modes: reduced to 2 states, the response error
    /// stays below the a-priori bound at every frequency, and keeping all states is exact.
    #[test]
    fn error_within_the_hankel_bound() {
        let a = three_modes(6);
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

    /// A slow state the input does not reach but the output sees (a disturbance model's, at
    /// 1 − 10⁻¹²) beside three fast modes: removed before the gramians, so the balanced
    /// realisation of the rest is exact and its truncation within the Hankel bound.
    #[test]
    fn a_slow_state_the_input_does_not_reach_is_removed_first() {
        let mut a = three_modes(7);
        a[(6, 6)] = 1.0 - 1e-12;
        // The fast modes mixed by a rotation; the slow state coupled to them only through the
        // output (so the observability gramian mixes it with all of them).
        let mut q = DMatrix::<f64>::identity(7, 7);
        q.view_mut((0, 0), (6, 6)).copy_from(
            &DMatrix::<f64>::from_fn(6, 6, |i, j| libm::sin((i * 6 + j) as f64 + 0.5))
                .qr()
                .q(),
        );
        let b0 = DMatrix::from_column_slice(7, 1, &[1.0, 0.0, 0.3, 0.1, 0.05, 0.02, 0.0]);
        let c0 = DMatrix::from_row_slice(1, 7, &[1.0, 0.5, 0.2, -0.1, 0.05, 0.01, 1.0]);
        let sys = StateSpace {
            a: &q * a * q.transpose(),
            b: &q * b0,
            c: c0 * q.transpose(),
            d: DMatrix::from_element(1, 1, 0.1),
        };
        let bal = Balancing::new(&sys).unwrap();
        assert_eq!(bal.minimal_order(), 6);
        let (full, red) = (bal.truncate(7), bal.truncate(2));
        assert_eq!(full.sys.nx(), 6);
        // The slow state's constant contribution is not in the response from the input.
        for i in 0..200 {
            let f = i as f64 / 400.0;
            let g = sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            let gf = full.sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            let gr = red.sys.freq_response_discrete(f, 1.0).unwrap()[(0, 0)];
            assert!((g - gf).norm() < 1e-9 * g.norm(), "f {f}");
            assert!((g - gr).norm() <= red.error_bound * (1.0 + 1e-9), "f {f}");
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
