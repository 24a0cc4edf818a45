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
//! Hewer 1971: the iterates stay stabilising and fall monotonically to it). Its first step is
//! kept whenever it stabilises: near the boundary, where the iteration is linear with ratio ½,
//! it can raise the residual on the way.
//!
//! A result is returned only when its closed loop is stable and its residual, relative to the
//! size of the terms the equation sums, is at most [`RESIDUAL_BOUND`]. Each closed-loop
//! eigenvalue is either resolved from the stability boundary — farther than ten first-order
//! perturbation bounds from it as an eigenvalue of the Hamiltonian (continuous), or farther
//! than rounding (discrete) ([`resolution`]), as CAREX 14's pair 5·10⁻¹³ from the axis is —
//! or kept off it by the data's structure where rounding cannot tell: with `Q − SR⁻¹Sᵀ`
//! positive semi-definite, the Hamiltonian's (pencil's) eigenvalues on the boundary are modes
//! of `A` on it that the penalty does not see or the input cannot move, and when there are none
//! the solution from the stable invariant subspace is returned with a warning
//! ([`Riccati::near_boundary`], a [`NearBoundary`]: the eigenvalue's distance from the boundary,
//! its first-order perturbation bound, the estimated forward error). Its polish is then Newton's
//! own steps from the start (a chord step, on an earlier closed loop's Schur form, has that
//! eigenvalue off by more than its distance and wanders), of which the stable iterate with the
//! least residual is kept: rounding moves the eigenvalue by up to its bound at each step, to
//! either side. Refused are what is shown to be on the boundary to working
//! precision — a mode of `A` there unseen or unmoved ([`RiccatiError::UnseenBoundaryMode`],
//! [`RiccatiError::Unstabilisable`]); with a penalty that is not semi-definite, an eigenvalue
//! within ten bounds of it ([`RiccatiError::HamiltonianOnAxis`],
//! [`RiccatiError::MarginalClosedLoop`]) — and what is shown not to stabilise (the closed loop
//! computed unstable beyond rounding, [`RiccatiError::NotStabilising`]). The equation's
//! relative condition number and the forward error it implies ([`condition`]) are estimated
//! when first asked for ([`Riccati::sensitivity`]: about twenty Lyapunov solves, which a design
//! that only needs `X` does not pay; a solution returned with a warning has it computed
//! already). Failures name their reason from the data where it shows one ([`diagnose`]).

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
    /// The Hamiltonian has an eigenvalue on the imaginary axis to working precision — within its
    /// first-order perturbation bound of it, with a penalty `Q − SR⁻¹Sᵀ` that is not
    /// semi-definite, so that nothing in the data's structure keeps it off (as a double
    /// eigenvalue on the axis is computed) — and no stabilising solution exists. (With a
    /// semi-definite penalty an eigenvalue on the axis is a boundary mode of `A`, reported as
    /// [`RiccatiError::UnseenBoundaryMode`] or [`RiccatiError::Unstabilisable`].)
    #[error("the Hamiltonian has the eigenvalue {eigenvalue} on the imaginary axis to working precision (within its perturbation bound, and Q is indefinite, so no structure keeps it off): no stabilising solution exists")]
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
    /// The closed loop is stable by less than the data's eigenvalues can be resolved, and the
    /// penalty `Q − SR⁻¹Sᵀ` is not semi-definite, so that nothing in the data's structure keeps
    /// the boundary clear: stabilisation cannot be told apart from a mode on the boundary
    /// (where no stabilising solution exists). With a semi-definite penalty such a solution is
    /// returned with [`Riccati::near_boundary`] instead.
    #[error("the closed loop's {measure} {value:.3e} is within {resolution:.1e} of the stability boundary, closer than its eigenvalues can be resolved, and Q is indefinite: no stabilising solution can be established")]
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

/// A warning on a returned solution: a closed-loop eigenvalue nearer the stability boundary
/// than working precision can tell it from the boundary (within ten times its first-order
/// perturbation bound). The penalty `Q − SR⁻¹Sᵀ` is positive semi-definite to working precision
/// and no mode of `A` on the boundary goes unseen by it or unmoved by the input, which keeps
/// every eigenvalue of the Hamiltonian (continuous) or symplectic pencil (discrete) off the
/// boundary under any perturbation of the data that keeps the penalties semi-definite: the
/// solution is the one the stable invariant subspace gives, polished by Newton's method, and its
/// closed loop is stable — but that eigenvalue, and with it `X`, is only known to the accuracy
/// given here (see `forward_error` before relying on digits of `X`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearBoundary {
    /// The closed-loop eigenvalue nearest the boundary.
    pub eigenvalue: Mode,
    /// The boundary: `"imaginary axis"` (continuous) or `"unit circle"` (discrete).
    pub boundary: &'static str,
    /// The eigenvalue's distance from the boundary: `−Re λ` (continuous) or `1 − |λ|`
    /// (discrete).
    pub distance: f64,
    /// Its first-order perturbation bound, how far rounding (a relative ε in the data and in the
    /// computation) can move it: `κ(λ)·ε·‖H‖` as an eigenvalue of the balanced Hamiltonian `H`
    /// (continuous, `κ = ‖x‖‖y‖/|yᴴx|` Wilkinson's condition number), or rounding,
    /// `10·ε·(1 + ‖A‖)` (discrete). `distance` is at most ten of these.
    pub bound: f64,
    /// The solution's estimated relative forward error ([`Sensitivity::forward_error`], as
    /// [`Riccati::sensitivity`] gives it).
    pub forward_error: f64,
}

impl std::fmt::Display for NearBoundary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the closed-loop eigenvalue {} is {:.2e} from the {}, within ten times its \
             first-order perturbation bound {:.2e}, so working precision cannot tell it from the \
             {}; the solution returned is the stable invariant subspace's, which a penalty \
             semi-definite to working precision and no unseen or unmoved mode on the {} keep \
             off it, with an estimated relative forward error of {:.1e}",
            self.eigenvalue,
            self.distance,
            self.boundary,
            self.bound,
            self.boundary,
            self.boundary,
            self.forward_error
        )
    }
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
    /// `Some` when a closed-loop eigenvalue cannot be told from the stability boundary at
    /// working precision and the solution is returned on the strength of the data's structure
    /// (see [`NearBoundary`]); `None` when every closed-loop eigenvalue is resolved from it.
    pub near_boundary: Option<NearBoundary>,
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
    let direct = attempt(&p, start, &p.q0, Route::Direct);
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
    match attempt(&p, start, &regularised, Route::Regularised) {
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
    /// The closed-loop eigenvalue that cannot be told from the boundary, if any (the penalty
    /// then being semi-definite).
    unresolved: Option<resolution::Unresolved>,
}

/// The start with penalty `q`, Newton's refinement (at most [`POLISH_STEPS`] after the direct
/// start, [`NEWTON_STEPS`] after a regularised one — whose first step is kept when it
/// stabilises even if it raises the residual; near the boundary with a semi-definite penalty,
/// Newton's own steps and the stable iterate with the least residual) and the checks: stable;
/// resolved from the boundary, or the penalty semi-definite (the caller then checks the data's
/// boundary modes: the closed loop is within [`BOUNDARY_SUSPECT`]); residual within
/// [`RESIDUAL_BOUND`].
fn attempt(
    p: &Problem,
    start: Start,
    q: &DMatrix<f64>,
    route: Route,
) -> Result<Found, RiccatiError> {
    let x = start(p, q).map_err(|iterations| RiccatiError::NoConvergence { iterations })?;
    let m = p.measure(x.clone()).ok_or(RiccatiError::SingularR)?;
    let steps = match route {
        Route::Direct => POLISH_STEPS,
        Route::Regularised => NEWTON_STEPS,
    };
    let (mut m, mut taken) = p.refine(m, steps);
    // Where the polished sequence starts, and the steps before it.
    let (mut origin, mut first) = (x, 0);
    if route == Route::Regularised && taken == 0 && m.relative > RESIDUAL_BOUND {
        // The first step raised the residual: near the boundary Kleinman's iterates fall
        // monotonically all the same, so take it when it stabilises and go on from there.
        if let Some(next) = p.kleinman_step(&m) {
            origin = next.x.clone();
            first = 1;
            (m, taken) = p.refine(next, steps - 1);
        }
    }
    taken += first;
    let mut eigenvalues = m.eigenvalues();
    let (mut measure, mut value, mut stable) = p.stability(&eigenvalues);
    // Near the boundary (an eigenvalue unresolved, or computed unstable by no more than rounding
    // can move it) with a semi-definite penalty, or a regularised start refined to an unstable
    // closed loop: Newton's own steps from the origin instead, the stable iterate with the
    // least residual. A chord step solves on an earlier closed loop, whose eigenvalue there is
    // off by up to its bound — more than its distance — and so wanders along that direction
    // once the residual is rounding; rounding can put the polished closed loop across the
    // boundary; and near it a chord step can overshoot across it by far more than rounding
    // (a mode 5·10⁻⁹ outside the unit circle, mirrored inside by the first steps, landed
    // 1.4·10⁻⁹ outside it), where Kleinman's and Hewer's own iterates from a stabilising start
    // stay stabilising.
    let near = if stable {
        resolution::closed_loop(p, eigenvalues.clone()).is_some()
    } else {
        resolution::instability_unresolved(p, &eigenvalues)
    };
    let overshot = !stable && route == Route::Regularised;
    if (near && resolution::semidefinite_penalty(p)) || overshot {
        if let Some((newton, newton_taken)) = p
            .measure(origin)
            .and_then(|start| p.refine_stable(start, steps - first))
        {
            (m, taken) = (newton, newton_taken + first);
            eigenvalues = m.eigenvalues();
            (measure, value, stable) = p.stability(&eigenvalues);
        }
    }
    if !stable {
        return Err(RiccatiError::NotStabilising { measure, value });
    }
    let unresolved = resolution::closed_loop(p, eigenvalues);
    if let Some(u) = unresolved.filter(|_| !resolution::semidefinite_penalty(p)) {
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
        unresolved,
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

/// The result in the caller's basis, with what its sensitivity is estimated from (estimated now
/// when a closed-loop eigenvalue is unresolved: the warning carries it).
fn finish(p: Problem, found: Found, route: Route) -> Riccati {
    let (x, k) = p.unscaled(&found.solution.x, &found.solution.k);
    let sensitivity = OnceLock::new();
    let near_boundary = found.unresolved.map(|u| {
        let estimate = *sensitivity.get_or_init(|| condition::sensitivity(&p, &found.solution));
        let l = u.eigenvalue;
        let (boundary, distance) = match p.kind {
            Kind::Continuous => ("imaginary axis", -l.re),
            Kind::Discrete => ("unit circle", 1.0 - l.norm()),
        };
        NearBoundary {
            eigenvalue: Mode::of(l),
            boundary,
            distance,
            bound: u.bound,
            forward_error: estimate.forward_error,
        }
    });
    Riccati {
        residual: found.solution.relative,
        closed_loop: found.closed_loop,
        newton_steps: found.newton_steps,
        route,
        near_boundary,
        x,
        k,
        deferred: Arc::new(Deferred {
            problem: p,
            solution: found.solution,
            sensitivity,
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
mod tests;
