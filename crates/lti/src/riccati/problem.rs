//! One Riccati equation, continuous or discrete, with everything evaluated on its original data:
//! the gain and closed loop of a candidate `X`, the residual beside the size of the terms that
//! make it up, the Newton step (Kleinman / Hewer) and the closed loop's stability.

use super::RiccatiError;
use crate::schur_lyapunov::{SchurForm, Side};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::sync::{Arc, OnceLock};

/// Continuous (`AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0`) or discrete
/// (`AᵀXA − X − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q = 0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Continuous,
    Discrete,
}

/// The data of one equation in a balanced state basis `x = D·x̃` (`D` diagonal, powers of two,
/// balancing `Ā`: `Ã = D⁻¹AD`, `B̃ = D⁻¹B`, `Q̃ = DQD`, `S̃ = DS`, solution `X̃ = DXD`), with its
/// cross-term-free form `Ā = A − BR⁻¹Sᵀ`, `Q̄ = Q − SR⁻¹Sᵀ`, `G = BR⁻¹Bᵀ` (what the starting
/// iterations work on). Every norm, residual and error is taken in this basis, where a state
/// measured in metres and one in volts weigh alike.
pub(super) struct Problem {
    pub kind: Kind,
    pub a: DMatrix<f64>,
    pub b: DMatrix<f64>,
    pub q: DMatrix<f64>,
    pub r: DMatrix<f64>,
    /// `S` (zero when absent), n × m.
    pub s: DMatrix<f64>,
    /// The diagonal of `D`.
    pub d: DVector<f64>,
    pub a0: DMatrix<f64>,
    pub q0: DMatrix<f64>,
    pub g: DMatrix<f64>,
}

/// A candidate solution measured: its gain, closed loop and residual.
pub(super) struct Measured {
    pub x: DMatrix<f64>,
    pub k: DMatrix<f64>,
    pub closed: DMatrix<f64>,
    /// The residual matrix.
    pub residual: DMatrix<f64>,
    /// `Σ ‖term‖_F` over the terms the equation sums.
    pub terms: f64,
    /// `‖residual‖_F / terms`.
    pub relative: f64,
    /// The closed loop's Schur form, computed once when first needed (Newton's step and the
    /// condition estimate both solve on it).
    schur: OnceLock<Option<Arc<SchurForm>>>,
}

/// Below this relative residual a chord step (on an earlier closed loop's Schur form) that
/// lowers the residual at all is kept: what remains is rounding, which Newton's own step would
/// not remove either.
const ROUNDING: f64 = 1e-13;

/// Above [`ROUNDING`], a chord step must lower the residual by this factor; a slower one is
/// retaken as Newton's step on the current closed loop (whose quadratic convergence the
/// regularised route needs).
const CHORD_GAIN: f64 = 0.25;

impl Measured {
    /// The closed loop's Schur form (`None` when its QZ iteration does not converge).
    pub fn schur(&self) -> Option<&Arc<SchurForm>> {
        self.schur
            .get_or_init(|| SchurForm::new(&self.closed).map(Arc::new))
            .as_ref()
    }

    /// The closed loop's eigenvalues (from its Schur form, which the condition estimate needs
    /// anyway).
    pub fn eigenvalues(&self) -> Vec<Complex64> {
        self.schur().map_or_else(
            || crate::state_space::eigenvalues(&self.closed),
            |s| s.eigenvalues(),
        )
    }
}

/// Stagnation of a starting iteration: its relative change has been below `small` and has set
/// no new minimum for [`Stall::PATIENCE`] steps (rounding, not convergence, now sets it:
/// Newton's method takes over).
#[derive(Debug)]
pub(super) struct Stall {
    small: f64,
    best: Option<f64>,
    since: usize,
}

impl Stall {
    const PATIENCE: usize = 3;

    /// Watching for stagnation below the relative change `small`.
    pub fn below(small: f64) -> Self {
        Stall {
            small,
            best: None,
            since: 0,
        }
    }

    /// Records a step's change; whether the iteration has stalled.
    pub fn stalled(&mut self, change: f64) -> bool {
        match self.best {
            Some(b) if change >= b => self.since += 1,
            _ => {
                self.best = Some(change);
                self.since = 0;
            }
        }
        self.best.is_some_and(|b| b < self.small) && self.since >= Self::PATIENCE
    }
}

pub(super) fn symmetric(x: DMatrix<f64>) -> DMatrix<f64> {
    (&x + x.transpose()) * 0.5
}

impl Problem {
    /// Shapes checked, `R` positive definite, the basis balanced, the cross term removed.
    pub fn new(
        kind: Kind,
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
        s: Option<&DMatrix<f64>>,
    ) -> Result<Self, RiccatiError> {
        let (n, m) = (a.nrows(), b.ncols());
        if a.ncols() != n
            || b.nrows() != n
            || q.shape() != (n, n)
            || r.shape() != (m, m)
            || s.is_some_and(|s| s.shape() != (n, m))
        {
            return Err(RiccatiError::Shape("A n×n, B n×m, Q n×n, R m×m, S n×m"));
        }
        if [a, b, q, r]
            .iter()
            .any(|m| m.iter().any(|v| !v.is_finite()))
            || s.is_some_and(|s| s.iter().any(|v| !v.is_finite()))
        {
            return Err(RiccatiError::NotFinite);
        }
        let r_inv = r
            .clone()
            .cholesky()
            .ok_or(RiccatiError::SingularR)?
            .inverse();
        let s = s.cloned().unwrap_or_else(|| DMatrix::zeros(n, m));
        let d = DVector::from_vec(crate::state_space::balance(a - b * &r_inv * s.transpose()).1);
        let (a, b, q, s) = (
            DMatrix::from_fn(n, n, |i, j| a[(i, j)] * d[j] / d[i]),
            DMatrix::from_fn(n, m, |i, j| b[(i, j)] / d[i]),
            DMatrix::from_fn(n, n, |i, j| q[(i, j)] * d[i] * d[j]),
            DMatrix::from_fn(n, m, |i, j| s[(i, j)] * d[i]),
        );
        let a0 = &a - &b * &r_inv * s.transpose();
        let q0 = symmetric(&q - &s * &r_inv * s.transpose());
        let g = symmetric(&b * &r_inv * b.transpose());
        Ok(Problem {
            kind,
            a,
            b,
            q,
            r: r.clone(),
            s,
            d,
            a0,
            q0,
            g,
        })
    }

    /// `X` and `K` back in the caller's basis: `X = D⁻¹X̃D⁻¹`, `K = K̃D⁻¹`.
    pub fn unscaled(&self, x: &DMatrix<f64>, k: &DMatrix<f64>) -> (DMatrix<f64>, DMatrix<f64>) {
        let d = &self.d;
        (
            DMatrix::from_fn(x.nrows(), x.ncols(), |i, j| x[(i, j)] / (d[i] * d[j])),
            DMatrix::from_fn(k.nrows(), k.ncols(), |i, j| k[(i, j)] / d[j]),
        )
    }

    pub fn n(&self) -> usize {
        self.a.nrows()
    }

    /// The gain `K` (`u = −Kx`) of `x`, or `None` when its denominator is singular.
    pub fn gain(&self, x: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        let (den, num) = match self.kind {
            Kind::Continuous => (self.r.clone(), self.b.transpose() * x + self.s.transpose()),
            Kind::Discrete => (
                &self.r + self.b.transpose() * x * &self.b,
                self.b.transpose() * x * &self.a + self.s.transpose(),
            ),
        };
        den.cholesky().map(|c| c.solve(&num))
    }

    /// `x`'s gain, closed loop and residual (`None`: singular denominator or not finite).
    pub fn measure(&self, x: DMatrix<f64>) -> Option<Measured> {
        let x = symmetric(x);
        let k = self.gain(&x)?;
        let (terms, residual) = match self.kind {
            Kind::Continuous => {
                let ax = self.a.transpose() * &x;
                let coupled = (&x * &self.b + &self.s) * &k;
                let norms = self.q.norm() + 2.0 * ax.norm() + coupled.norm();
                (norms, &ax + ax.transpose() - coupled + &self.q)
            }
            Kind::Discrete => {
                let axa = self.a.transpose() * &x * &self.a;
                let coupled = (self.a.transpose() * &x * &self.b + &self.s) * &k;
                let norms = axa.norm() + coupled.norm() + self.q.norm() + x.norm();
                (norms, axa - coupled + &self.q - &x)
            }
        };
        let residual = symmetric(residual);
        let terms = terms.max(f64::MIN_POSITIVE);
        let relative = residual.norm() / terms;
        relative.is_finite().then(|| Measured {
            closed: &self.a - &self.b * &k,
            x,
            k,
            residual,
            terms,
            relative,
            schur: OnceLock::new(),
        })
    }

    /// The stability measure of a closed loop with `eigenvalues`: spectral radius (discrete)
    /// or abscissa (continuous), with its name and whether it is stable.
    pub fn stability(&self, eigenvalues: &[Complex64]) -> (&'static str, f64, bool) {
        match self.kind {
            Kind::Continuous => Self::hurwitz_of(eigenvalues),
            Kind::Discrete => {
                let v = eigenvalues.iter().map(|l| l.norm()).fold(0.0, f64::max);
                ("spectral radius", v, v < 1.0)
            }
        }
    }

    /// The Hamiltonian `[Ā −G; −Q̄ −Āᵀ]`.
    pub fn hamiltonian(&self) -> DMatrix<f64> {
        let n = self.n();
        let mut h = DMatrix::zeros(2 * n, 2 * n);
        h.view_mut((0, 0), (n, n)).copy_from(&self.a0);
        h.view_mut((0, n), (n, n)).copy_from(&(-&self.g));
        h.view_mut((n, 0), (n, n)).copy_from(&(-&self.q0));
        h.view_mut((n, n), (n, n))
            .copy_from(&(-self.a0.transpose()));
        h
    }

    /// The spectral abscissa of `a`, its name and whether it is negative.
    pub fn hurwitz(a: &DMatrix<f64>) -> (&'static str, f64, bool) {
        Self::hurwitz_of(&crate::state_space::eigenvalues(a))
    }

    /// The spectral abscissa of `eigenvalues`, its name and whether it is negative.
    fn hurwitz_of(eigenvalues: &[Complex64]) -> (&'static str, f64, bool) {
        let v = eigenvalues
            .iter()
            .map(|l| l.re)
            .fold(f64::NEG_INFINITY, f64::max);
        ("spectral abscissa", v, v < 0.0)
    }

    /// One step in defect form on the Schur form of a closed loop `Ac`: `X + Δ` with
    /// `AcᵀΔ + ΔAc + Res = 0` (Kleinman) or `Δ = AcᵀΔAc + Res` (Hewer). Newton's step when `Ac`
    /// is `X`'s own closed loop, a chord step when it is an earlier iterate's.
    fn step(&self, m: &Measured, schur: &SchurForm) -> Option<Measured> {
        let delta = match self.kind {
            Kind::Continuous => schur.continuous(&m.residual, Side::Transposed),
            Kind::Discrete => schur.discrete(&m.residual, Side::Transposed),
        };
        let next = symmetric(&m.x + delta);
        if next.iter().all(|v| v.is_finite()) {
            self.measure(next)
        } else {
            None
        }
    }

    /// Kleinman's (Hewer's) step from `m`, a stabilising solution of a penalty above this one's,
    /// kept when its closed loop is stable whatever its residual: from such a start the
    /// iterates fall monotonically to the stabilising solution and stay stabilising, but near a
    /// boundary (the Fréchet derivative nearly singular at the solution) the first step can
    /// raise the residual that [`Problem::refine`] asks to fall.
    pub fn kleinman_step(&self, m: &Measured) -> Option<Measured> {
        let own = m.schur()?.clone();
        self.step(m, &own)
            .filter(|next| self.stability(&next.eigenvalues()).2)
    }

    /// Newton's steps from `m` (each on the current closed loop's own Schur form) while they
    /// lower the relative residual, at most `steps`, and the first that does not; of these
    /// iterates (`m` included) the one with a stable closed loop and the least residual, and the
    /// steps taken to it — `None` when none is stable. For a closed-loop eigenvalue that cannot
    /// be told from the boundary: [`Problem::refine`]'s chord steps, on an earlier closed loop
    /// whose eigenvalue there is off by more than its distance, wander along that direction once
    /// the residual is rounding; and each step moves the eigenvalue by up to its perturbation
    /// bound, to either side, so that a choice by residual alone may land on the wrong one.
    pub fn refine_stable(&self, m: Measured, steps: usize) -> Option<(Measured, usize)> {
        let mut best: Option<(Measured, usize)> = None;
        let mut offer = |candidate: Measured, taken: usize| {
            if self.stability(&candidate.eigenvalues()).2
                && best
                    .as_ref()
                    .is_none_or(|(b, _)| candidate.relative < b.relative)
            {
                best = Some((candidate, taken));
            }
        };
        let mut current = m;
        let mut taken = 0;
        loop {
            let next = if taken < steps {
                current
                    .schur()
                    .cloned()
                    .and_then(|own| self.step(&current, &own))
            } else {
                None
            };
            let improves = next.as_ref().is_some_and(|n| n.relative < current.relative);
            offer(current, taken);
            match next {
                Some(n) if improves => {
                    current = n;
                    taken += 1;
                }
                Some(n) => {
                    offer(n, taken + 1);
                    break;
                }
                None => break,
            }
        }
        best
    }

    /// Steps from `m` while they lower the relative residual, at most `steps`; the best
    /// candidate and the number of steps that improved it. Steps are taken on the Schur form of
    /// the last closed loop one was computed for (chord steps: a Schur form is as costly as
    /// the rest of a step together) while that lowers the residual fast enough
    /// ([`CHORD_GAIN`], [`ROUNDING`]); otherwise on the current closed loop's own (Newton's
    /// step), which is then kept. The best candidate's own Schur form is computed when the
    /// chord stalls, which the stability check and the condition estimate then use.
    pub fn refine(&self, mut best: Measured, steps: usize) -> (Measured, usize) {
        let mut taken = 0;
        let mut frozen: Option<Arc<SchurForm>> = None;
        for _ in 0..steps {
            if best.relative <= f64::EPSILON {
                break;
            }
            let chord = frozen
                .as_ref()
                .and_then(|f| self.step(&best, f))
                .filter(|next| {
                    next.relative < CHORD_GAIN * best.relative
                        || (next.relative < best.relative && best.relative <= ROUNDING)
                });
            let next = match chord {
                Some(next) => Some(next),
                None => best.schur().cloned().and_then(|own| {
                    let next = self.step(&best, &own);
                    frozen = Some(own);
                    next
                }),
            };
            match next {
                Some(next) if next.relative < best.relative => {
                    best = next;
                    taken += 1;
                }
                _ => break,
            }
        }
        (best, taken)
    }
}
