//! The analyses of a configuration: the error budget and the loop's frequency responses and
//! margins — what `servo budget` and `servo frf --model` compute, as Python values.

use crate::arrays::vector;
use crate::config::{built, load, plan};
use crate::servo_err;
use loop_model::closed_loop::{input, output, ClosedLoop};
use pyo3::prelude::*;
use pyo3::types::PyDict;

/// The error budget of `config` with `overrides` on `points` log-spaced frequencies, with the
/// loop's margins and −3 dB bandwidth: the JSON of `servo budget --json`'s `budget`, plus
/// `margins` and `bandwidth_hz`.
#[pyfunction]
#[pyo3(signature = (config=None, overrides=None, points=400))]
pub fn budget(
    py: Python<'_>,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
    points: usize,
) -> PyResult<String> {
    let loaded = load(config, overrides)?;
    py.detach(|| {
        let plan = built(&loaded)?;
        let a = studies::budget::analyse(&plan, points).map_err(servo_err)?;
        let json = serde_json::json!({
            "budget": a.budget,
            "margins": a.margins,
            "bandwidth_hz": a.budget.bandwidth_hz,
            "controller": plan.controller.description,
        });
        Ok(json.to_string())
    })
}

/// Frequency responses of `config`'s sampled loop at `freq_hz` (complex arrays): the plant
/// `measured_m / command_v` (no controller), the closed loop `measured_m / reference_m`, and
/// the sensitivity `following_error_m / reference_m`.
#[pyfunction]
#[pyo3(signature = (freq_hz, config=None, overrides=None))]
pub fn loop_response<'py>(
    py: Python<'py>,
    freq_hz: Vec<f64>,
    config: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let plan = plan(config, overrides)?;
    let open = ClosedLoop::open(&plan.sim, plan.config.plant.capa.sensitivity_v_per_m)
        .ok_or_else(|| servo_err("plant.actuator.model = \"coil\" has no exact sampled model"))?;
    let at = |l: &ClosedLoop, out: usize, inp: usize| -> PyResult<Vec<num_complex::Complex64>> {
        freq_hz
            .iter()
            .map(|&f| l.response(out, inp, f).map_err(servo_err))
            .collect()
    };
    let d = PyDict::new(py);
    d.set_item("freq_hz", vector(py, freq_hz.clone()))?;
    let cl = &plan.closed_loop;
    let plant = at(&open, output::MEASURED_M, input::CONTROL_DISTURBANCE_V)?;
    d.set_item("plant_m_per_v", vector(py, plant))?;
    d.set_item(
        "closed_loop",
        vector(py, at(cl, output::MEASURED_M, input::REFERENCE_M)?),
    )?;
    d.set_item(
        "sensitivity",
        vector(py, at(cl, output::FOLLOWING_ERROR_M, input::REFERENCE_M)?),
    )?;
    Ok(d)
}
