//! The one clarabel call the design tools share: a quadratic (or linear) program with linear
//! inequalities, `min ½xᵀPx + qᵀx` subject to `A x ≤ b`.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, NonnegativeConeT, SolverStatus,
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
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .build()
        .expect("valid clarabel settings");
    let cones = [NonnegativeConeT(rows.len())];
    let mut solver =
        DefaultSolver::new(&p, q, &a, b, &cones, settings).map_err(|e| format!("{e:?}"))?;
    solver.solve();
    match solver.solution.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => Ok(solver.solution.x.clone()),
        s => Err(format!("{s:?}")),
    }
}
