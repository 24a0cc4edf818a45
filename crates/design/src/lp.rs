//! The clarabel calls the design tools share: a quadratic (or linear) program with linear
//! inequalities, `min ½xᵀPx + qᵀx` subject to `A x ≤ b`, and a linear objective over
//! equalities and second-order cones (least squares in epigraph form, solved to the residual's
//! own relative precision).

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT,
    SolverStatus, ZeroConeT,
};

/// Solves `min ½xᵀPx + qᵀx` s.t. `rows · x ≤ b`; `p_upper` holds the upper triangle of P
/// (None: a linear program). Returns the solution, or clarabel's status when it did not solve.
pub(crate) fn solve(
    p_upper: Option<&[Vec<f64>]>,
    q: &[f64],
    rows: &[Vec<f64>],
    b: &[f64],
) -> Result<Vec<f64>, String> {
    let n = q.len();
    let p = match p_upper {
        Some(p) => CscMatrix::from(p),
        None => CscMatrix::<f64>::zeros((n, n)),
    };
    let a = CscMatrix::from(rows);
    let cones = [NonnegativeConeT(rows.len())];
    run(&p, q, &a, b, &cones)
}

/// A block of constraint rows: `rows · x = b`, or `b − rows · x` in a second-order cone
/// (its first entry bounds the norm of the rest).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Block {
    /// Equalities, this many rows.
    Equal(usize),
    /// One second-order cone of this dimension.
    Cone(usize),
}

/// Solves `min qᵀx` subject to the row `blocks` (in order over `rows`, `b`).
pub(crate) fn solve_conic(
    q: &[f64],
    rows: &[Vec<f64>],
    b: &[f64],
    blocks: &[Block],
) -> Result<Vec<f64>, String> {
    let n = q.len();
    let cones: Vec<_> = blocks
        .iter()
        .map(|c| match *c {
            Block::Equal(m) => ZeroConeT(m),
            Block::Cone(m) => SecondOrderConeT(m),
        })
        .collect();
    run(
        &CscMatrix::<f64>::zeros((n, n)),
        q,
        &CscMatrix::from(rows),
        b,
        &cones,
    )
}

fn run(
    p: &CscMatrix<f64>,
    q: &[f64],
    a: &CscMatrix<f64>,
    b: &[f64],
    cones: &[clarabel::solver::SupportedConeT<f64>],
) -> Result<Vec<f64>, String> {
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .expect("valid clarabel settings");
    let mut solver =
        DefaultSolver::new(p, q, a, b, cones, settings).map_err(|e| format!("{e:?}"))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(solver.solution.x.clone()),
        s => Err(format!("{s:?}")),
    }
}
