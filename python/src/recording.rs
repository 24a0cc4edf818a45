//! Frames as columns: what a run streams and what a recording holds, as NumPy arrays.

use crate::arrays::vector;
use crate::servo_err;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use recorder::{Frame, TelemetryRecord, TruthRecord};
use runner::recording::{FrameSink, RunHeader};
use std::path::PathBuf;

/// One column per recorded field, filled frame by frame.
#[derive(Default)]
pub struct Columns {
    time_s: Vec<f64>,
    telemetry: [Vec<f32>; TelemetryRecord::LEN],
    truth: [Vec<f32>; TruthRecord::LEN],
    header: Option<(String, String)>,
}

impl Columns {
    /// Appends one frame.
    pub fn push(&mut self, f: &Frame) {
        self.time_s.push(f.time_ns as f64 * 1e-9);
        for (col, v) in self.telemetry.iter_mut().zip(f.telemetry.values()) {
            col.push(v);
        }
        for (col, v) in self.truth.iter_mut().zip(f.truth.values()) {
            col.push(v);
        }
    }

    /// `{"time_s": …, "telemetry": {field: …}, "truth": {field: …}}` (time float64, the
    /// recorded fields float32 as recorded; SI units, the field names say which).
    pub fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let out = PyDict::new(py);
        out.set_item("time_s", vector(py, self.time_s))?;
        let group = |names: &[&str], cols: Vec<Vec<f32>>| -> PyResult<Bound<'_, PyDict>> {
            let d = PyDict::new(py);
            for (name, col) in names.iter().zip(cols) {
                d.set_item(name, vector(py, col))?;
            }
            Ok(d)
        };
        out.set_item(
            "telemetry",
            group(TelemetryRecord::FIELDS, self.telemetry.into())?,
        )?;
        out.set_item("truth", group(TruthRecord::FIELDS, self.truth.into())?)?;
        if let Some((config, controller)) = self.header {
            out.set_item("config_toml", config)?;
            out.set_item("controller", controller)?;
        }
        Ok(out)
    }
}

impl FrameSink for Columns {
    fn header(&mut self, h: &RunHeader) -> Result<(), runner::RunError> {
        self.header = Some((h.loaded.config.to_toml(), h.controller.clone()));
        Ok(())
    }

    fn frame(&mut self, f: &Frame) {
        self.push(f);
    }
}

/// Reads recording `path` (an MCAP file `servo run` or `servo record` wrote) into columns, with
/// its configuration, controller and summary. A damaged or unfinished file raises, unless
/// `salvage` (then what is intact is read, and `read` says what was skipped).
#[pyfunction]
#[pyo3(signature = (path, salvage = false))]
pub fn read_recording(py: Python<'_>, path: PathBuf, salvage: bool) -> PyResult<Bound<'_, PyDict>> {
    let mut columns = Columns::default();
    let read = py
        .detach(|| runner::recording::inspect_with(&path, &mut columns)?.intact(&path, salvage))
        .map_err(servo_err)?;
    let out = columns.into_dict(py)?;
    out.set_item(
        "summary_json",
        serde_json::to_string(&read.summary).map_err(servo_err)?,
    )?;
    out.set_item("end", read.end.into_iter().collect::<Vec<_>>())?;
    out.set_item(
        "finished",
        matches!(read.read.state, recorder::FileState::Finished),
    )?;
    out.set_item("read", read.read.to_string())?;
    Ok(out)
}
