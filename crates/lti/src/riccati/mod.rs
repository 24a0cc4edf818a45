//! Algebraic Riccati equations, continuous and discrete, solved so that a result can be trusted:
//!
//! * CARE `AᵀX + XA − (XB + S)R⁻¹(BᵀX + Sᵀ) + Q = 0`: a start by the matrix sign function of
//!   the Hamiltonian ([`continuous`]);
//! * DARE `X = AᵀXA − (AᵀXB + S)(R + BᵀXB)⁻¹(BᵀXA + Sᵀ) + Q`: a start by structure-preserving
//!   doubling ([`discrete`]; no inverse of `A`, so delay chains with singular `A` are fine);
//! * then Newton's method on the equation itself (Kleinman / Hewer, [`problem`]), each step a
//!   Lyapunov or Stein equation on the closed loop's Schur form, while it lowers the residual.
//!
//! When the start is not the stabilising solution (an unstable mode the penalty does not see:
//! doubling then converges to the smallest solution) or does not converge, the penalty is
//! regularised to `Q + δI` (every mode seen), whose solution stabilises the loop, and Newton's
//! method from it converges to the stabilising solution of the original equation (Kleinman 1968,
//! Hewer 1971: the iterates stay stabilising and fall monotonically to it).
//!
//! A result is returned only when its closed loop is stable by more than its eigenvalues can be
//! resolved ([`resolution`]: continuous, each eigenvalue's own perturbation bound as an
//! eigenvalue of the Hamiltonian, so a simple pair a hair from the axis is told from a double
//! one on it; discrete: rounding, boundary modes being checked before solving) and its
//! residual, relative to the size of the terms the equation sums, is at most
//! [`RESIDUAL_BOUND`]. The equation's relative condition number and the forward error it
//! implies ([`condition`]) are estimated when first asked for ([`Riccati::sensitivity`]: about
//! twenty Lyapunov solves, which a design that only needs `X` does not pay). Failures name
//! their reason from the data where it shows one ([`diagnose`]).

mod condition;
mod continuous;
mod diagnose;
mod discrete;
mod problem;
mod resolution;

use nalgebra::DMatrix;
use problem::{Kind, Measured, Problem};
use std::sync::{Arc, OnceLock};

pub use condition::Sensitivity;

/// The largest residual a returned solution may have: `‖Res(X)‖_F / Σ‖term‖_F` over the terms
/// the equation sums (a backward error: the data would have to change by about this much,
/// relatively, for `X` to solve them exactly). Norms, residuals and errors are taken in a
/// balanced state basis `x = D·x̃` (`D` diagonal, powers of two, balancing `A`; `X̃ = DXD`),
/// where states in metres and in volts weigh alike: entry `(i, j)` of `X` is accurate relative
/// to `√(X̃ᵢᵢX̃ⱼⱼ)/(dᵢdⱼ)`.
pub const RESIDUAL_BOUND: f64 = 1e-10;

/// How near the stability boundary (relative, as [`Found::margin`]) a directly found closed
/// loop must come for the data's boundary modes to be checked: a mode on the boundary that the
/// input cannot move or the penalty does not see is a double eigenvalue of the Hamiltonian
/// or symplectic pencil, which rounding splits by about `√(κ·ε)` — within this margin for any
/// condition `κ` below 10¹⁰.
const BOUNDARY_SUSPECT: f64 = 1e-3;

/// Newton steps after a start that converged (polishing).
const POLISH_STEPS: usize = 4;

/// Newton steps after a regularised start (it begins a relative `δ` away).
const NEWTON_STEPS: usize = 40;

/// The regularisation of the penalty, relative to the problem's scale.
const REGULARISATION: f64 = 1e-6;

/// An eigenvalue, in the unit of the equation's time base (rad/s, or per step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
}

impl Mode {
    fn of(l: num_complex::Complex64) -> Self {
        Mode { re: l.re, im: l.im }
    }
}

impl std::fmt::Display for Mode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{:.6e} {:+.6e}i", self.re, self.im)
    }
}

/// Why a Riccati or Lyapunov equation has no (stabilising) solution here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum RiccatiError {
    /// Matrix shapes do not fit.
    #[error("shape mismatch: {0}")]
    Shape(&'static str),
    /// An entry of the data is NaN or infinite.
    #[error("an entry of A, B, Q, R or S is not finite")]
    NotFinite,
    /// `R` (or `R + BᵀXB`) is singular or not positive definite.
    #[error("R is not positive definite")]
    SingularR,
    /// An unstable (or marginal) mode the input cannot move: `(A, B)` is not stabilisable.
    #[error("the mode λ = {mode} is not stable and the input cannot move it: (A, B) is not stabilisable")]
    Unstabilisable {
        /// The mode.
        mode: Mode,
    },
    /// A mode on the stability boundary that the penalty does not see: no solution stabilises
    /// it.
    #[error("the mode λ = {mode} lies on the stability boundary and the penalty Q does not see it: no stabilising solution")]
    UnseenBoundaryMode {
        /// The mode.
        mode: Mode,
    },
    /// The Hamiltonian has an eigenvalue on the imaginary axis: no stabilising solution exists.
    #[error("the Hamiltonian has the eigenvalue {eigenvalue} on the imaginary axis: no stabilising solution exists")]
    HamiltonianOnAxis {
        /// The eigenvalue nearest the axis.
        eigenvalue: Mode,
    },
    /// The iteration did not converge and the data show no reason.
    #[error(
        "no stabilising solution found (the iteration did not converge after {iterations} steps)"
    )]
    NoConvergence {
        /// Steps taken.
        iterations: usize,
    },
    /// A solution was found but does not stabilise the closed loop.
    #[error("the solution does not stabilise the loop (closed-loop {measure} = {value})")]
    NotStabilising {
        /// Spectral radius (discrete) or abscissa (continuous).
        measure: &'static str,
        /// Its value.
        value: f64,
    },
    /// The closed loop is stable by less than the data's eigenvalues can be resolved:
    /// stabilisation cannot be told apart from a mode on the boundary (where no stabilising
    /// solution exists).
    #[error("the closed loop's {measure} {value:.3e} is within {resolution:.1e} of the stability boundary, closer than its eigenvalues can be resolved: no stabilising solution can be established")]
    MarginalClosedLoop {
        /// Spectral radius (discrete) or abscissa (continuous).
        measure: &'static str,
        /// Its value.
        value: f64,
        /// How close to the boundary an eigenvalue cannot be told from it.
        resolution: f64,
    },
    /// The best solution found leaves a residual above [`RESIDUAL_BOUND`].
    #[error("the best solution found leaves a relative residual of {residual:.2e}, above the bound {bound:.0e}")]
    ResidualAboveBound {
        /// Its relative residual.
        residual: f64,
        /// [`RESIDUAL_BOUND`].
        bound: f64,
    },
}

/// How a solution was reached.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Route {
    /// The sign function (continuous) or doubling (discrete), then Newton's polishing.
    Direct,
    /// A regularised penalty's solution, then Newton's method on the equation.
    Regularised,
}

/// A Riccati solution and how far to trust it.
#[derive(Debug, Clone)]
pub struct Riccati {
    /// The stabilising solution X (symmetric).
    pub x: DMatrix<f64>,
    /// The optimal gain `K` with `u = −K x`.
    pub k: DMatrix<f64>,
    /// Relative residual `‖Res(X)‖_F / Σ‖term‖_F`, at most [`RESIDUAL_BOUND`] (in the balanced
    /// state basis, as the estimates of [`Riccati::sensitivity`]: see [`RESIDUAL_BOUND`]).
    pub residual: f64,
    /// Closed-loop spectral radius (discrete) or spectral abscissa (continuous) of `A − BK`.
    pub closed_loop: f64,
    /// Refinement steps that lowered the residual (Newton's, or chord steps on an earlier
    /// closed loop's Schur form).
    pub newton_steps: usize,
    /// How the solution was reached.
    pub route: Route,
    /// What the sensitivity is estimated from, and the estimate once asked for.
    deferred: Arc<Deferred>,
}

/// The balanced problem and its measured solution (with the closed loop's Schur form), kept
/// until the sensitivity is asked for.
struct Deferred {
    problem: Problem,
    solution: Measured,
    sensitivity: OnceLock<Sensitivity>,
}

impl std::fmt::Debug for Deferred {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Deferred")
            .field("sensitivity", &self.sensitivity.get())
            .finish_non_exhaustive()
    }
}

impl Riccati {
    /// The equation's relative condition number and the solution's estimated forward error,
    /// computed on the first call (power iterations on the closed loop's Schur form: about
    /// twenty Lyapunov or Stein solves, as long as the solve itself) and kept.
    pub fn sensitivity(&self) -> Sensitivity {
        let d = &*self.deferred;
        *d.sensitivity
            .get_or_init(|| condition::sensitivity(&d.problem, &d.solution))
    }
}

/// [`care`] or [`dare`]: `(A, B, Q, R, S)` to the stabilising solution (one signature, so that a
/// design can take either).
pub type Solver = fn(
    &DMatrix<f64>,
    &DMatrix<f64>,
    &DMatrix<f64>,
    &DMatrix<f64>,
    Option<&DMatrix<f64>>,
) -> Result<Riccati, RiccatiError>;

/// Continuous algebraic Riccati equation (optional cross term `S`).
pub fn care(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Riccati, RiccatiError> {
    solve(
        Problem::new(Kind::Continuous, a, b, q, r, s)?,
        continuous::sign_start,
    )
}

/// Discrete algebraic Riccati equation (optional cross term `S`).
pub fn dare(
    a: &DMatrix<f64>,
    b: &DMatrix<f64>,
    q: &DMatrix<f64>,
    r: &DMatrix<f64>,
    s: Option<&DMatrix<f64>>,
) -> Result<Riccati, RiccatiError> {
    solve(
        Problem::new(Kind::Discrete, a, b, q, r, s)?,
        discrete::doubling_start,
    )
}

/// A starting iteration: `X` for the cross-term-free problem with the given penalty, or the
/// steps it took before failing.
type Start = fn(&Problem, &DMatrix<f64>) -> Result<DMatrix<f64>, usize>;

/// The direct route, then the regularised one; the first result that is stabilising and
/// within the residual bound, or the reason there is none. Modes of `A` on the stability
/// boundary that the input cannot move or the penalty does not see ([`diagnose::boundary_modes`]:
/// no stabilising solution exists, but a solver can land near such a mode and look
/// stabilising) are looked for when they can matter: before the regularised route, and after
/// the direct one when its closed loop comes within [`BOUNDARY_SUSPECT`] of the boundary.
fn solve(p: Problem, start: Start) -> Result<Riccati, RiccatiError> {
    let direct = attempt(&p, start, &p.q0, POLISH_STEPS);
    if direct
        .as_ref()
        .map_or(true, |f| f.margin <= BOUNDARY_SUSPECT)
    {
        if let Some(e) = diagnose::boundary_modes(&p) {
            return Err(e);
        }
    }
    let first = match direct {
        Ok(found) => return Ok(finish(p, found, Route::Direct)),
        Err(e) => e,
    };
    let n = p.n();
    let regularised = &p.q0 + DMatrix::<f64>::identity(n, n) * regularisation(&p);
    match attempt(&p, start, &regularised, NEWTON_STEPS) {
        Ok(found) => Ok(finish(p, found, Route::Regularised)),
        Err(_) => Err(diagnose::diagnose(&p).unwrap_or(first)),
    }
}

/// A solution that passed every check: the measured candidate, the Newton steps that improved
/// it and its closed loop's stability measure.
struct Found {
    solution: Measured,
    newton_steps: usize,
    closed_loop: f64,
    /// How far the closed loop is from the stability boundary, relative: `1 − ρ` (discrete)
    /// or `−α/‖Ā‖` (continuous).
    margin: f64,
}

/// The start with penalty `q`, Newton's refinement (at most `steps`) and the checks: stable,
/// resolved from the boundary, residual within [`RESIDUAL_BOUND`].
fn attempt(
    p: &Problem,
    start: Start,
    q: &DMatrix<f64>,
    steps: usize,
) -> Result<Found, RiccatiError> {
    let x = start(p, q).map_err(|iterations| RiccatiError::NoConvergence { iterations })?;
    let m = p.measure(x).ok_or(RiccatiError::SingularR)?;
    let (m, taken) = p.refine(m, steps);
    let eigenvalues = m.eigenvalues();
    let (measure, value, stable) = p.stability(&eigenvalues);
    if !stable {
        return Err(RiccatiError::NotStabilising { measure, value });
    }
    if let Some(u) = resolution::closed_loop(p, eigenvalues) {
        return Err(RiccatiError::MarginalClosedLoop {
            measure,
            value: match p.kind {
                Kind::Continuous => u.eigenvalue.re,
                Kind::Discrete => u.eigenvalue.norm(),
            },
            resolution: u.resolution,
        });
    }
    if m.relative > RESIDUAL_BOUND {
        return Err(RiccatiError::ResidualAboveBound {
            residual: m.relative,
            bound: RESIDUAL_BOUND,
        });
    }
    let margin = match p.kind {
        Kind::Continuous => -value / p.a0.norm().max(f64::MIN_POSITIVE),
        Kind::Discrete => 1.0 - value,
    };
    Ok(Found {
        solution: m,
        newton_steps: taken,
        closed_loop: value,
        margin,
    })
}

/// `δ` of the regularised penalty `Q + δI`: a small fraction of `‖Q‖`, or of `‖A‖²/‖G‖` (the
/// scale a penalty must have to matter) when `Q` is zero.
fn regularisation(p: &Problem) -> f64 {
    let q = p.q0.norm();
    let scale = if q > 0.0 {
        q
    } else {
        let a = p.a0.norm().max(1.0);
        match p.kind {
            Kind::Continuous => a * a / p.g.norm().max(f64::MIN_POSITIVE),
            Kind::Discrete => 1.0,
        }
    };
    REGULARISATION * scale
}

/// The result in the caller's basis, with what its sensitivity is estimated from.
fn finish(p: Problem, found: Found, route: Route) -> Riccati {
    let (x, k) = p.unscaled(&found.solution.x, &found.solution.k);
    Riccati {
        residual: found.solution.relative,
        closed_loop: found.closed_loop,
        newton_steps: found.newton_steps,
        route,
        x,
        k,
        deferred: Arc::new(Deferred {
            problem: p,
            solution: found.solution,
            sensitivity: OnceLock::new(),
        }),
    }
}

/// Continuous Lyapunov `A X + X Aᵀ + Q = 0` for Hurwitz `A` (by the Schur form); returns `X`
/// and the relative residual.
pub fn lyap(a: &DMatrix<f64>, q: &DMatrix<f64>) -> Result<(DMatrix<f64>, f64), RiccatiError> {
    let n = a.nrows();
    if a.ncols() != n || q.shape() != (n, n) {
        return Err(RiccatiError::Shape("A and Q n×n"));
    }
    let (measure, value, stable) = Problem::hurwitz(a);
    if !stable {
        return Err(RiccatiError::NotStabilising { measure, value });
    }
    let schur = crate::schur_lyapunov::SchurForm::new(a)
        .ok_or(RiccatiError::NoConvergence { iterations: 0 })?;
    let x = problem::symmetric(schur.continuous(q, crate::schur_lyapunov::Side::Plain));
    let residual = (a * &x + &x * a.transpose() + q).norm() / x.norm().max(f64::MIN_POSITIVE);
    Ok((x, residual))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(r: usize, c: usize, v: &[f64]) -> DMatrix<f64> {
        DMatrix::from_row_slice(r, c, v)
    }

    /// Scalar LQR: 2ax − b²x²/r + q = 0 → x = r(a + √(a² + b²q/r))/b².
    #[test]
    fn scalar_care_closed_form() {
        for (a, b, q, r) in [
            (1.0, 1.0, 1.0, 1.0),
            (-2.0, 0.5, 3.0, 0.1),
            (1e3, 1.0, 1.0, 1.0),
        ] {
            let sol = care(
                &m(1, 1, &[a]),
                &m(1, 1, &[b]),
                &m(1, 1, &[q]),
                &m(1, 1, &[r]),
                None,
            )
            .unwrap();
            let want = r * (a + (a * a + b * b * q / r).sqrt()) / (b * b);
            assert!(
                (sol.x[(0, 0)] - want).abs() < 1e-10 * want,
                "{} vs {want}",
                sol.x[(0, 0)]
            );
            assert!(sol.residual < 1e-10 && sol.closed_loop < 0.0);
        }
    }

    /// Double-integrator LQR (Q = I, R = 1): X = [[√3, 1], [1, √3]], K = [1, √3].
    #[test]
    fn double_integrator_care() {
        let sol = care(
            &m(2, 2, &[0.0, 1.0, 0.0, 0.0]),
            &m(2, 1, &[0.0, 1.0]),
            &DMatrix::identity(2, 2),
            &m(1, 1, &[1.0]),
            None,
        )
        .unwrap();
        let s3 = 3f64.sqrt();
        for (got, want) in sol.x.iter().zip([s3, 1.0, 1.0, s3]) {
            assert!((got - want).abs() < 1e-12);
        }
        assert!((sol.k[(0, 0)] - 1.0).abs() < 1e-12 && (sol.k[(0, 1)] - s3).abs() < 1e-12);
        assert!(sol.residual < 1e-12);
    }

    /// Scalar DARE: x = a²x − a²b²x²/(r + b²x) + q, i.e. b²x² + (r − a²r − b²q)x − qr = 0.
    #[test]
    fn scalar_dare_closed_form() {
        for (a, b, q, r) in [
            (0.9, 1.0, 1.0, 1.0),
            (1.5, 0.3, 2.0, 0.5),
            (0.0, 1.0, 1.0, 1.0),
        ] {
            let sol = dare(
                &m(1, 1, &[a]),
                &m(1, 1, &[b]),
                &m(1, 1, &[q]),
                &m(1, 1, &[r]),
                None,
            )
            .unwrap();
            let (qa, qb, qc) = (b * b, r - a * a * r - b * b * q, -q * r);
            let want = (-qb + (qb * qb - 4.0 * qa * qc).sqrt()) / (2.0 * qa);
            assert!((sol.x[(0, 0)] - want).abs() < 1e-12 * want.max(1.0));
            assert!(sol.residual < 1e-12 && sol.closed_loop < 1.0);
        }
    }

    /// Riccati difference iteration X ← AᵀXA − AᵀXB(R + BᵀXB)⁻¹BᵀXA + Q, independent of SDA.
    fn value_iteration(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        q: &DMatrix<f64>,
        r: &DMatrix<f64>,
    ) -> DMatrix<f64> {
        let mut x = q.clone();
        for _ in 0..20_000 {
            let k = (r + b.transpose() * &x * b).try_inverse().unwrap() * b.transpose() * &x * a;
            x = a.transpose() * &x * a - a.transpose() * &x * b * k + q;
        }
        x
    }

    /// Singular A (a pure two-step delay chain in front of an unstable mode) and a
    /// cross-term problem: SDA agrees with the difference iteration, residual ≤ 1e-10.
    #[test]
    fn dare_with_singular_a_and_cross_term() {
        let a = m(3, 3, &[1.2, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0]);
        let b = m(3, 1, &[0.0, 0.0, 1.0]);
        let (q, r) = (DMatrix::identity(3, 3), m(1, 1, &[0.3]));
        let sol = dare(&a, &b, &q, &r, None).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
        let vi = value_iteration(&a, &b, &q, &r);
        assert!((&sol.x - &vi).norm() < 1e-9 * vi.norm());
        // Cross term: solve with S and compare with the transformed problem's iteration.
        let s = m(3, 1, &[0.1, 0.0, 0.2]);
        let sol = dare(&a, &b, &q, &r, Some(&s)).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
        let ri = r.clone().try_inverse().unwrap();
        let vi = value_iteration(
            &(&a - &b * &ri * s.transpose()),
            &b,
            &(&q - &s * &ri * s.transpose()),
            &r,
        );
        assert!((&sol.x - &vi).norm() < 1e-9 * vi.norm());
    }

    /// Unstabilisable pair: an unstable mode the input cannot reach has no stabilising solution.
    #[test]
    fn unstabilisable_pairs_are_errors() {
        let a = m(2, 2, &[1.5, 0.0, 0.0, 0.5]);
        let b = m(2, 1, &[0.0, 1.0]);
        assert!(dare(&a, &b, &DMatrix::identity(2, 2), &m(1, 1, &[1.0]), None).is_err());
        let ac = m(2, 2, &[1.0, 0.0, 0.0, -1.0]);
        assert!(care(&ac, &b, &DMatrix::identity(2, 2), &m(1, 1, &[1.0]), None).is_err());
    }

    /// Ill-conditioned CAREX-style case: widely separated time scales (1e-3 … 1e3 rad/s).
    #[test]
    fn widely_scaled_care() {
        let a = m(3, 3, &[-1e-3, 1.0, 0.0, 0.0, -1.0, 1.0, 0.0, 0.0, -1e3]);
        let b = m(3, 1, &[0.0, 0.0, 1e3]);
        let sol = care(&a, &b, &DMatrix::identity(3, 3), &m(1, 1, &[1.0]), None).unwrap();
        assert!(sol.residual < 1e-10, "{}", sol.residual);
    }

    #[test]
    fn continuous_lyapunov() {
        let a = m(2, 2, &[-1.0, 2.0, 0.0, -3.0]);
        let q = m(2, 2, &[2.0, 0.5, 0.5, 1.0]);
        let (x, res) = lyap(&a, &q).unwrap();
        assert!(res < 1e-12, "{res}");
        // Scalar closed form: 2ax + q = 0.
        let (x1, _) = lyap(&m(1, 1, &[-0.25]), &m(1, 1, &[3.0])).unwrap();
        assert!((x1[(0, 0)] - 6.0).abs() < 1e-12);
        assert!(x.symmetric_eigenvalues().iter().all(|&l| l > 0.0));
    }
}
