//! Discrete-time H2-optimal output feedback (the SLICOT SB10ED problem) on a generalized plant
//!
//! ```text
//! x⁺ = A x + B1 w + B2 u
//! z  = C1 x          + D12 u        (D11 = 0)
//! y  = C2 x + D21 w                 (D22 = 0: a strictly proper plant from u to y)
//! ```
//!
//! Control DARE `X` (Q = C1ᵀC1, R = D12ᵀD12, S = C1ᵀD12) and filter DARE `Y` (the dual, with
//! B1B1ᵀ, D21D21ᵀ, B1D21ᵀ) give `F`, `L`, and the feed-through terms `F0`, `L0` of the optimal
//! controller that uses the current measurement (Zhou, Doyle & Glover, ch. 21):
//! `A_K = A + B2F + LC2 − B2L0C2`, `B_K = −(L − B2L0)`, `C_K = F − L0C2`, `D_K = L0`.
//!
//! The continuous problem (SLICOT SB10HD, [`h2syn_continuous`]) is the same with CAREs and a
//! strictly proper controller: `A_K = A + B2F + LC2`, `B_K = −L`, `C_K = F`.

use lti::riccati::{care, dare, lyap, Mode, NearBoundary, Riccati, RiccatiError, Solver};
use lti::{dlyap, StateSpace};
use nalgebra::DMatrix;

/// A generalized plant for H2 synthesis.
#[derive(Debug, Clone)]
pub struct GeneralizedPlant {
    /// n × n.
    pub a: DMatrix<f64>,
    /// Disturbance input, n × nw.
    pub b1: DMatrix<f64>,
    /// Control input, n × nu.
    pub b2: DMatrix<f64>,
    /// Performance output, nz × n.
    pub c1: DMatrix<f64>,
    /// Measurement, ny × n.
    pub c2: DMatrix<f64>,
    /// nz × nu, full column rank.
    pub d12: DMatrix<f64>,
    /// ny × nw, full row rank.
    pub d21: DMatrix<f64>,
}

/// Synthesis errors, naming the condition that failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum H2Error {
    /// Shapes do not fit.
    #[error("shape mismatch: {0}")]
    Shape(&'static str),
    /// D12 must have full column rank (every control input is penalised).
    #[error("D12ᵀD12 is singular: every control input must appear in z (full column rank)")]
    D12Rank,
    /// D21 must have full row rank (every measurement is noisy).
    #[error("D21D21ᵀ is singular: every measurement needs noise (full row rank)")]
    D21Rank,
    /// A mode that is not stable and that the control input cannot move.
    #[error("the plant's mode λ = {mode} is not stable and u cannot move it: (A, B2) is not stabilisable")]
    Unstabilisable {
        /// The mode (rad/s continuous, per sample discrete).
        mode: Mode,
    },
    /// A mode that is not stable and that no measurement sees.
    #[error("the plant's mode λ = {mode} is not stable and y does not see it: (C2, A) is not detectable")]
    Undetectable {
        /// The mode.
        mode: Mode,
    },
    /// A mode on the stability boundary that the performance output does not see: the optimal
    /// loop would leave it there.
    #[error("the plant's mode λ = {mode} lies on the stability boundary and z does not see it: no stabilising H2 controller is optimal")]
    UnpenalisedBoundaryMode {
        /// The mode.
        mode: Mode,
    },
    /// A mode on the stability boundary that the disturbance does not drive: the optimal
    /// estimator would not track it.
    #[error("the plant's mode λ = {mode} lies on the stability boundary and w does not drive it: no stabilising H2 estimator is optimal")]
    UndrivenBoundaryMode {
        /// The mode.
        mode: Mode,
    },
    /// The control Riccati equation failed for another reason.
    #[error("control Riccati equation: {0}")]
    Control(RiccatiError),
    /// The filter Riccati equation failed for another reason.
    #[error("filter Riccati equation: {0}")]
    Filter(RiccatiError),
}

impl H2Error {
    /// The control equation's failure in the plant's terms.
    fn control(e: RiccatiError) -> Self {
        match e {
            RiccatiError::Unstabilisable { mode } => H2Error::Unstabilisable { mode },
            RiccatiError::UnseenBoundaryMode { mode } => H2Error::UnpenalisedBoundaryMode { mode },
            e => H2Error::Control(e),
        }
    }

    /// The filter (dual) equation's failure in the plant's terms.
    fn filter(e: RiccatiError) -> Self {
        match e {
            RiccatiError::Unstabilisable { mode } => H2Error::Undetectable { mode },
            RiccatiError::UnseenBoundaryMode { mode } => H2Error::UndrivenBoundaryMode { mode },
            e => H2Error::Filter(e),
        }
    }
}

/// The synthesized controller and what it achieves.
#[derive(Debug, Clone)]
pub struct H2Controller {
    /// The controller `u = K(y)` as a discrete state space (same sample period as the plant).
    pub k: StateSpace,
    /// Closed-loop H2 norm from w to z (per sample: `√trace(C Wc Cᵀ + D Dᵀ)`).
    pub h2_norm: f64,
    /// Closed-loop spectral radius.
    pub spectral_radius: f64,
    /// What the Riccati equations warned of ([`Warning`]).
    pub warnings: Vec<Warning>,
}

/// A synthesis's Riccati equation whose solution came with a warning: its closed loop lies
/// nearer the stability boundary than working precision resolves ([`NearBoundary`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Warning {
    /// `control` (the state-feedback equation: the penalty on z, C1 and D12) or `filter`
    /// (the estimator's: the noise w, B1 and D21).
    pub equation: &'static str,
    /// What the solver found.
    pub near_boundary: NearBoundary,
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the {} Riccati equation: {}",
            self.equation, self.near_boundary
        )
    }
}

/// The warnings of the control equation `x` and the filter equation `y`.
fn warnings(x: &Riccati, y: &Riccati) -> Vec<Warning> {
    [("control", x), ("filter", y)]
        .into_iter()
        .filter_map(|(equation, r)| {
            r.near_boundary.map(|near_boundary| Warning {
                equation,
                near_boundary,
            })
        })
        .collect()
}

impl GeneralizedPlant {
    fn check(&self) -> Result<(usize, usize, usize, usize, usize), H2Error> {
        let n = self.a.nrows();
        let (nw, nu, nz, ny) = (
            self.b1.ncols(),
            self.b2.ncols(),
            self.c1.nrows(),
            self.c2.nrows(),
        );
        let ok = self.a.shape() == (n, n)
            && self.b1.nrows() == n
            && self.b2.nrows() == n
            && self.c1.ncols() == n
            && self.c2.ncols() == n
            && self.d12.shape() == (nz, nu)
            && self.d21.shape() == (ny, nw);
        if ok {
            Ok((n, nw, nu, nz, ny))
        } else {
            Err(H2Error::Shape(
                "A n×n, B1 n×nw, B2 n×nu, C1 nz×n, C2 ny×n, D12 nz×nu, D21 ny×nw",
            ))
        }
    }

    /// The same plant in diagonally balanced state coordinates (Parlett–Reinsch on the whole
    /// system matrix).
    pub fn balanced(&self) -> GeneralizedPlant {
        let (n, nw) = (self.a.nrows(), self.b1.ncols());
        let (nz, nu, ny) = (self.c1.nrows(), self.b2.ncols(), self.c2.nrows());
        let mut b = DMatrix::zeros(n, nw + nu);
        b.view_mut((0, 0), (n, nw)).copy_from(&self.b1);
        b.view_mut((0, nw), (n, nu)).copy_from(&self.b2);
        let mut c = DMatrix::zeros(nz + ny, n);
        c.view_mut((0, 0), (nz, n)).copy_from(&self.c1);
        c.view_mut((nz, 0), (ny, n)).copy_from(&self.c2);
        let sys = StateSpace {
            a: self.a.clone(),
            b,
            c,
            d: DMatrix::zeros(nz + ny, nw + nu),
        }
        .balanced();
        GeneralizedPlant {
            a: sys.a,
            b1: sys.b.columns(0, nw).into_owned(),
            b2: sys.b.columns(nw, nu).into_owned(),
            c1: sys.c.rows(0, nz).into_owned(),
            c2: sys.c.rows(nz, ny).into_owned(),
            d12: self.d12.clone(),
            d21: self.d21.clone(),
        }
    }

    /// The closed loop of this plant with controller `k`: `(A, B, C, D)` from w to z.
    pub fn close(&self, k: &StateSpace) -> StateSpace {
        let (n, nk) = (self.a.nrows(), k.nx());
        let mut a = DMatrix::zeros(n + nk, n + nk);
        a.view_mut((0, 0), (n, n))
            .copy_from(&(&self.a + &self.b2 * &k.d * &self.c2));
        a.view_mut((0, n), (n, nk)).copy_from(&(&self.b2 * &k.c));
        a.view_mut((n, 0), (nk, n)).copy_from(&(&k.b * &self.c2));
        a.view_mut((n, n), (nk, nk)).copy_from(&k.a);
        let mut b = DMatrix::zeros(n + nk, self.b1.ncols());
        b.view_mut((0, 0), (n, b.ncols()))
            .copy_from(&(&self.b1 + &self.b2 * &k.d * &self.d21));
        b.view_mut((n, 0), (nk, b.ncols()))
            .copy_from(&(&k.b * &self.d21));
        let mut c = DMatrix::zeros(self.c1.nrows(), n + nk);
        c.view_mut((0, 0), (c.nrows(), n))
            .copy_from(&(&self.c1 + &self.d12 * &k.d * &self.c2));
        c.view_mut((0, n), (c.nrows(), nk))
            .copy_from(&(&self.d12 * &k.c));
        let d = &self.d12 * &k.d * &self.d21;
        StateSpace { a, b, c, d }
    }
}

/// The rank checks both syntheses need, then the control equation `X` (C1ᵀC1, R1 = D12ᵀD12,
/// C1ᵀD12) and the filter equation `Y` (the dual: B1B1ᵀ, R2 = D21D21ᵀ, B1D21ᵀ) by `riccati`.
/// Returns `(R1, R2, X, Y)`.
fn riccati_pair(
    p: &GeneralizedPlant,
    riccati: Solver,
) -> Result<(DMatrix<f64>, DMatrix<f64>, Riccati, Riccati), H2Error> {
    let r1 = p.d12.transpose() * &p.d12;
    let r2 = &p.d21 * p.d21.transpose();
    if r1.clone().cholesky().is_none() {
        return Err(H2Error::D12Rank);
    }
    if r2.clone().cholesky().is_none() {
        return Err(H2Error::D21Rank);
    }
    let x = riccati(
        &p.a,
        &p.b2,
        &(p.c1.transpose() * &p.c1),
        &r1,
        Some(&(p.c1.transpose() * &p.d12)),
    )
    .map_err(H2Error::control)?;
    let y = riccati(
        &p.a.transpose(),
        &p.c2.transpose(),
        &(&p.b1 * p.b1.transpose()),
        &r2,
        Some(&(&p.b1 * p.d21.transpose())),
    )
    .map_err(H2Error::filter)?;
    Ok((r1, r2, x, y))
}

/// H2 norm of a stable discrete system from its controllability gramian.
pub fn h2_norm_discrete(sys: &StateSpace) -> Option<f64> {
    let (wc, _) = dlyap(&sys.a, &(&sys.b * sys.b.transpose())).ok()?;
    Some(((&sys.c * wc * sys.c.transpose()).trace() + (&sys.d * sys.d.transpose()).trace()).sqrt())
}

/// A continuous H2-optimal controller and what it achieves.
#[derive(Debug, Clone)]
pub struct H2ContinuousController {
    /// The controller `u = K(y)` (strictly proper).
    pub k: StateSpace,
    /// Closed-loop H2 norm from w to z: `√trace(C Wc Cᵀ)`, `A Wc + Wc Aᵀ + B Bᵀ = 0`.
    pub h2_norm: f64,
    /// Closed-loop spectral abscissa (largest real part of a pole; < 0: stable).
    pub spectral_abscissa: f64,
    /// What the Riccati equations warned of ([`Warning`]).
    pub warnings: Vec<Warning>,
}

/// H2 norm of a stable, strictly proper continuous system from its controllability gramian
/// (None if it is not stable or has feed-through, where the norm is infinite).
pub fn h2_norm_continuous(sys: &StateSpace) -> Option<f64> {
    if sys.d.iter().any(|v| *v != 0.0) {
        return None;
    }
    let (wc, _) = lyap(&sys.a, &(&sys.b * sys.b.transpose())).ok()?;
    Some((&sys.c * wc * sys.c.transpose()).trace().max(0.0).sqrt())
}

/// Synthesizes the continuous H2-optimal controller for `p` (SB10HD-equivalent): control CARE
/// `X` (C1ᵀC1, D12ᵀD12, cross C1ᵀD12), filter CARE `Y` (B1B1ᵀ, D21D21ᵀ, cross B1D21ᵀ),
/// `F = −(D12ᵀD12)⁻¹(B2ᵀX + D12ᵀC1)`, `L = −(Y C2ᵀ + B1D21ᵀ)(D21D21ᵀ)⁻¹`.
pub fn h2syn_continuous(original: &GeneralizedPlant) -> Result<H2ContinuousController, H2Error> {
    original.check()?;
    // Solve in diagonally balanced state coordinates (the controller's input-output map does
    // not depend on them): a plant whose poles span decades otherwise stalls the sign iteration.
    let mut scaled = original.balanced();
    // Normalise the noise (‖D21‖ = 1) and the penalty (‖D12‖ = 1): the gains F and L do not
    // change, and the two Riccati equations are no longer "cheap" by accident of units.
    let (sw, sz) = (scaled.d21.norm(), scaled.d12.norm());
    if sw > 0.0 && sz > 0.0 {
        scaled.b1 /= sw;
        scaled.d21 /= sw;
        scaled.c1 /= sz;
        scaled.d12 /= sz;
    }
    let p = &scaled;
    let (_, _, x, y) = riccati_pair(p, care)?;
    let f = -&x.k;
    let l = -y.k.transpose();
    let k = StateSpace {
        a: &p.a + &p.b2 * &f + &l * &p.c2,
        b: -&l,
        c: f,
        d: DMatrix::zeros(p.b2.ncols(), p.c2.nrows()),
    };
    let cl = original.close(&k);
    let abscissa = cl
        .poles()
        .iter()
        .map(|z| z.re)
        .fold(f64::NEG_INFINITY, f64::max);
    let h2 = h2_norm_continuous(&cl).unwrap_or(f64::INFINITY);
    Ok(H2ContinuousController {
        k,
        h2_norm: h2,
        spectral_abscissa: abscissa,
        warnings: warnings(&x, &y),
    })
}

/// Synthesizes the discrete H2-optimal controller for `p`.
pub fn h2syn_discrete(p: &GeneralizedPlant) -> Result<H2Controller, H2Error> {
    p.check()?;
    let (r1, r2, x, y) = riccati_pair(p, dare)?;
    let (xm, ym) = (&x.x, &y.x);
    let f = -&x.k; // u = F x
    let l = -y.k.transpose(); // x̂⁺ = … + L(C2 x̂ − y)
    let rx = (&r1 + p.b2.transpose() * xm * &p.b2)
        .try_inverse()
        .ok_or(H2Error::D12Rank)?;
    let ry = (&r2 + &p.c2 * ym * p.c2.transpose())
        .try_inverse()
        .ok_or(H2Error::D21Rank)?;
    let f0 = -&rx * p.b2.transpose() * xm * &p.b1;
    let l0 = (&f * ym * p.c2.transpose() + &f0 * p.d21.transpose()) * &ry;
    let k = StateSpace {
        a: &p.a + &p.b2 * &f + &l * &p.c2 - &p.b2 * &l0 * &p.c2,
        b: -(&l - &p.b2 * &l0),
        c: &f - &l0 * &p.c2,
        d: l0,
    };
    let cl = p.close(&k);
    let radius = cl.poles().iter().map(|z| z.norm()).fold(0.0, f64::max);
    let h2 = h2_norm_discrete(&cl).unwrap_or(f64::INFINITY);
    Ok(H2Controller {
        k,
        h2_norm: h2,
        spectral_radius: radius,
        warnings: warnings(&x, &y),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
        DMatrix::from_row_slice(r, c, v)
    }

    /// A sampled double integrator (T = 0.1) with force and sensor noise, position and effort
    /// penalised: a textbook discrete LQG problem.
    fn double_integrator() -> GeneralizedPlant {
        let t = 0.1;
        GeneralizedPlant {
            a: m(2, 2, &[1.0, t, 0.0, 1.0]),
            b1: m(2, 2, &[t * t / 2.0, 0.0, t, 0.0]),
            b2: m(2, 1, &[t * t / 2.0, t]),
            c1: m(2, 2, &[1.0, 0.0, 0.0, 0.0]),
            c2: m(1, 2, &[1.0, 0.0]),
            d12: m(2, 1, &[0.0, 0.3]),
            d21: m(1, 2, &[0.0, 0.05]),
        }
    }

    #[test]
    fn stabilises_and_norms_agree() {
        let p = double_integrator();
        let c = h2syn_discrete(&p).unwrap();
        assert!(c.spectral_radius < 1.0);
        // The H2 norm from the observability gramian equals the controllability one.
        let cl = p.close(&c.k);
        let (wo, _) = dlyap(&cl.a.transpose(), &(cl.c.transpose() * &cl.c)).unwrap();
        let via_wo =
            ((cl.b.transpose() * wo * &cl.b).trace() + (&cl.d.transpose() * &cl.d).trace()).sqrt();
        assert!(
            (via_wo / c.h2_norm - 1.0).abs() < 1e-10,
            "{via_wo} vs {}",
            c.h2_norm
        );
        // And from the frequency response: ‖T‖² = (1/2π)∫|T(e^{jθ})|²_F dθ (fine midpoint rule).
        let n = 20_000;
        let mut acc = 0.0;
        for i in 0..n {
            let f = (i as f64 + 0.5) / n as f64 * 0.5; // cycles per sample, 0 … ½
            let h = cl.freq_response_discrete(f, 1.0).unwrap();
            acc += h.iter().map(|x| x.norm_sqr()).sum::<f64>() / n as f64;
        }
        assert!((acc.sqrt() / c.h2_norm - 1.0).abs() < 1e-4);
    }

    /// Optimality: random perturbations of the controller never lower the closed-loop H2 norm.
    #[test]
    fn perturbations_do_not_improve_it() {
        let p = double_integrator();
        let c = h2syn_discrete(&p).unwrap();
        let mut seed = 7u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        for _ in 0..200 {
            let e = 1e-3;
            let mut k = c.k.clone();
            k.a.iter_mut().for_each(|x| *x += e * rnd());
            k.b.iter_mut().for_each(|x| *x += e * rnd());
            k.c.iter_mut().for_each(|x| *x += e * rnd());
            k.d.iter_mut().for_each(|x| *x += e * rnd());
            let cl = p.close(&k);
            if cl.poles().iter().all(|z| z.norm() < 1.0) {
                let n = h2_norm_discrete(&cl).unwrap();
                assert!(
                    n >= c.h2_norm * (1.0 - 1e-9),
                    "perturbed {n} < optimal {}",
                    c.h2_norm
                );
            }
        }
    }

    /// With (nearly) perfect state measurement the output-feedback cost approaches the LQR
    /// (full information) cost √trace(B1ᵀXB1) from above.
    #[test]
    fn approaches_the_full_information_optimum() {
        let mut p = double_integrator();
        p.c2 = DMatrix::identity(2, 2);
        p.b1 = m(2, 4, &[0.005, 0.0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0]);
        p.d21 = m(2, 4, &[0.0, 0.0, 1e-6, 0.0, 0.0, 0.0, 0.0, 1e-6]);
        let c = h2syn_discrete(&p).unwrap();
        let x = dare(
            &p.a,
            &p.b2,
            &(p.c1.transpose() * &p.c1),
            &(p.d12.transpose() * &p.d12),
            None,
        )
        .unwrap();
        let full_info = (p.b1.transpose() * &x.x * &p.b1).trace().sqrt();
        assert!(c.h2_norm >= full_info * (1.0 - 1e-9));
        assert!(
            (c.h2_norm / full_info - 1.0) < 1e-4,
            "{} vs {full_info}",
            c.h2_norm
        );
    }

    #[test]
    fn rank_conditions_are_named() {
        let mut p = double_integrator();
        p.d12 = m(2, 1, &[0.0, 0.0]);
        assert_eq!(h2syn_discrete(&p).unwrap_err(), H2Error::D12Rank);
        let mut p = double_integrator();
        p.d21 = m(1, 2, &[0.0, 0.0]);
        assert_eq!(h2syn_discrete(&p).unwrap_err(), H2Error::D21Rank);
    }
}
