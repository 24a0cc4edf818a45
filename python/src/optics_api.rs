//! `prescription_sag`: a surface prescription file's sag and slopes at points.

use crate::arrays::vector;
use crate::servo_err;
use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use std::path::PathBuf;

/// The prescription of `path` (TOML, Zemax conventions, mm) read and checked as a run reads
/// it; its sag z (m) and slopes ∂z/∂x, ∂z/∂y at the points `(x_m, y_m)` (m, the part's frame).
#[pyfunction]
#[allow(clippy::type_complexity)]
pub fn prescription_sag<'py>(
    py: Python<'py>,
    path: PathBuf,
    x_m: PyReadonlyArray1<'_, f64>,
    y_m: PyReadonlyArray1<'_, f64>,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    let p = run_config::read_prescription(&path).map_err(servo_err)?;
    let (x, y) = (x_m.as_slice()?, y_m.as_slice()?);
    if x.len() != y.len() {
        return Err(servo_err(format!(
            "x_m and y_m differ in length ({} and {})",
            x.len(),
            y.len()
        )));
    }
    let sags: Vec<_> = x.iter().zip(y).map(|(&x, &y)| p.sag(x, y)).collect();
    Ok((
        vector(py, sags.iter().map(|s| s.z_m).collect()),
        vector(py, sags.iter().map(|s| s.dz_dx).collect()),
        vector(py, sags.iter().map(|s| s.dz_dy).collect()),
    ))
}
