//! Design-space studies from Python: the pieces a distributed run needs — the study's size,
//! the rows of any set of points (what a Ray task computes), the study folder's journal to
//! append them to (resumable, shared with `servo study`), and the finish that writes the table
//! and summary from the folders' journals (as `servo study merge`, which draws the plots too).

use crate::servo_err;
use pyo3::prelude::*;
use std::path::PathBuf;
use studies::design_space::evaluate::evaluate;
use studies::design_space::journal::{claim, pending, Journal, Shard};
use studies::design_space::spec::Study;
use studies::design_space::table::{header, row};
use studies::design_space::{finish, gather};

fn parse(text: &str) -> PyResult<Study> {
    Study::parse(text, None).map_err(servo_err)
}

/// `(points, header)` of the study described by `text`.
#[pyfunction]
pub fn study_info(text: &str) -> PyResult<(u64, String)> {
    let s = parse(text)?;
    Ok((s.points(), header(&s)))
}

/// The table rows (CSV lines, newline-terminated) of points `indices` of the study `text`,
/// evaluated one after another in this thread (the GIL released).
#[pyfunction]
pub fn study_rows(py: Python<'_>, text: &str, indices: Vec<u64>) -> PyResult<Vec<String>> {
    let s = parse(text)?;
    if let Some(bad) = indices.iter().find(|&&i| i >= s.points()) {
        return Err(servo_err(format!(
            "point {bad}: allowed 0..{} (the study's points)",
            s.points()
        )));
    }
    Ok(py.detach(|| indices.iter().map(|&i| row(&evaluate(&s, i))).collect()))
}

/// Makes `out_dir` the study's folder (refusing one that holds another study) and opens the
/// whole-study journal there (the one `servo study` resumes); returns its path and the points
/// it does not hold yet.
#[pyfunction]
pub fn study_open(text: &str, out_dir: PathBuf) -> PyResult<(PathBuf, Vec<u64>)> {
    let s = parse(text)?;
    claim(&s, &out_dir).map_err(servo_err)?;
    let (_, done) = Journal::open(&s, &out_dir, Shard::ALL).map_err(servo_err)?;
    Ok((
        out_dir.join(Shard::ALL.file_name()),
        pending(&s, Shard::ALL, &done),
    ))
}

/// Joins the journals in `dirs` and writes the finished study into `out_dir` (the
/// sensitivities on every core); returns the written file paths.
#[pyfunction]
pub fn study_finish(
    py: Python<'_>,
    dirs: Vec<PathBuf>,
    out_dir: PathBuf,
) -> PyResult<Vec<PathBuf>> {
    py.detach(|| {
        let (s, points) = gather(&dirs).map_err(servo_err)?;
        claim(&s, &out_dir).map_err(servo_err)?;
        let jobs = std::thread::available_parallelism().map_or(1, |n| n.get());
        let (_, written) =
            finish(&s, &points, &out_dir, jobs, &mut |_, _| {}).map_err(servo_err)?;
        Ok(written.files)
    })
}
