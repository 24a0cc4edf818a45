//! `run`: the closed loop in process, its frames as columns and its summary.

use crate::config::{built, load};
use crate::recording::Columns;
use crate::servo_err;
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// Runs the closed loop of `config` with `overrides` to its end (no recording) and returns
/// `{"summary_json", "config_toml", "controller", "time_s", "telemetry", "truth"}` — the same
/// loop and the same numbers as `servo run` with that configuration and seed.
#[pyfunction]
#[pyo3(signature = (config=None, overrides=None))]
pub fn run<'py>(
    py: Python<'py>,
    config: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let loaded = load(config, overrides)?;
    let mut columns = Columns::default();
    // Without the GIL: other Python threads run meanwhile.
    let (config, controller, summary) = py.detach(|| {
        let plan = built(&loaded)?;
        let summary =
            runner::run::run_to_end_with(&plan, |f| columns.push(f)).map_err(servo_err)?;
        Ok::<_, PyErr>((plan.config, plan.controller.description, summary))
    })?;
    let out = columns.into_dict(py)?;
    out.set_item(
        "summary_json",
        serde_json::to_string(&summary).map_err(servo_err)?,
    )?;
    out.set_item("config_toml", config.to_toml())?;
    out.set_item("controller", controller)?;
    Ok(out)
}
