//! `prescription_sag`: a surface prescription file's sag and slopes at points; `read_map`: a
//! measured surface map.

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

/// The measured surface map in `path` read as `servo register` reads it: its heights (m,
/// `rows × cols`, image order, NaN without data), pixel pitch `(x, y)` (m) and format name;
/// `height_unit` (`m`, `mm`, `um`, `nm`) and `pitch_m` only for a file that does not state
/// them.
#[pyfunction]
#[pyo3(signature = (path, height_unit=None, pitch_m=None))]
#[allow(clippy::type_complexity)]
pub fn read_map<'py>(
    py: Python<'py>,
    path: PathBuf,
    height_unit: Option<String>,
    pitch_m: Option<f64>,
) -> PyResult<(Bound<'py, numpy::PyArray2<f64>>, (f64, f64), String)> {
    let height_unit = height_unit
        .map(|u| {
            metrology::LengthUnit::parse(&u)
                .ok_or_else(|| servo_err(format!("height_unit = '{u}': allowed m, mm, um, nm")))
        })
        .transpose()?;
    let options = metrology::ReadOptions {
        height_unit,
        pitch_m,
    };
    let m = metrology::read_map(&path, &options).map_err(servo_err)?;
    let heights = nalgebra::DMatrix::from_row_slice(m.rows, m.cols, &m.heights_m);
    Ok((
        crate::arrays::matrix(py, &heights),
        (m.pitch_m[0], m.pitch_m[1]),
        format!("{:?}", m.format),
    ))
}
