//! The models of a configuration as `(A, B, C, D, dt)` with signal names: python-control
//! takes them as `control.ss(A, B, C, D, dt)` (dt = 0: continuous time).

use crate::arrays::matrix;
use crate::config::plan;
use crate::servo_err;
use lti::StateSpace;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};
use runner::closed_loop::{self, ClosedLoop};

/// One model as a dict: `abcd_dt` (the 5-tuple), `inputs`, `outputs`, `what`.
pub fn model<'py>(
    py: Python<'py>,
    sys: &StateSpace,
    dt_s: f64,
    inputs: &[&str],
    outputs: &[&str],
    what: &str,
) -> PyResult<Bound<'py, PyDict>> {
    assert_eq!((sys.nu(), sys.ny()), (inputs.len(), outputs.len()));
    let d = PyDict::new(py);
    let abcd = PyTuple::new(
        py,
        [
            matrix(py, &sys.a).into_any(),
            matrix(py, &sys.b).into_any(),
            matrix(py, &sys.c).into_any(),
            matrix(py, &sys.d).into_any(),
            dt_s.into_pyobject(py)?.into_any(),
        ],
    )?;
    d.set_item("abcd_dt", abcd)?;
    d.set_item("inputs", inputs.to_vec())?;
    d.set_item("outputs", outputs.to_vec())?;
    d.set_item("what", what)?;
    Ok(d)
}

/// Every model of `config` with `overrides`: `mechanics` and `plant` (continuous), and at the
/// servo period `plant_sampled` (DAC command to the loop's outputs, no controller),
/// `controller` and `closed_loop`.
#[pyfunction]
#[pyo3(signature = (config=None, overrides=None))]
pub fn models<'py>(
    py: Python<'py>,
    config: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    use plant_sim::model;
    let plan = plan(config, overrides)?;
    let p = &plan.config.plant;
    let dt = plan.closed_loop.period_s;
    let out = PyDict::new(py);
    out.set_item(
        "mechanics",
        model(
            py,
            &model::mechanics(&p.stage),
            0.0,
            &model::MECHANICS_INPUTS,
            &model::MECHANICS_OUTPUTS,
            "the four-mass stage (DESIGN.md; thesis eq 5-4..5-7), continuous time",
        )?,
    )?;
    let whole = plant_sim::PlantModel::new(p).map_err(servo_err)?;
    out.set_item(
        "plant",
        model(
            py,
            &whole.sys,
            0.0,
            &model::input::NAMES,
            &model::output::NAMES,
            "stage, current loop, sensor and accelerometer chains and noise filters, continuous time",
        )?,
    )?;
    let sensitivity = p.capa.sensitivity_v_per_m;
    let open = ClosedLoop::open(&plan.sim, sensitivity).ok_or_else(|| {
        servo_err("plant.actuator.model = \"coil\" has no exact sampled model: use \"ideal\" or \"second_order\"")
    })?;
    let (ins, outs) = (&closed_loop::input::NAMES, &closed_loop::output::NAMES);
    out.set_item(
        "plant_sampled",
        model(py, &open.sys, dt, ins, outs, "the sampled plant without a controller (exact: zero-order hold, delay, averaging); the DAC command enters as control_disturbance_v")?,
    )?;
    let c = &plan.controller.linear;
    let controller = StateSpace {
        a: c.a.clone(),
        b: c.b.clone(),
        c: c.c.clone(),
        d: c.d.clone(),
    };
    out.set_item(
        "controller",
        model(
            py,
            &controller,
            dt,
            &["gap_v", "accel_v"],
            &["command_v"],
            &format!(
                "{} (zero reference; the PID acts on −gap_v)",
                plan.controller.description
            ),
        )?,
    )?;
    out.set_item(
        "closed_loop",
        model(
            py,
            &plan.closed_loop.sys,
            dt,
            ins,
            outs,
            "the sampled closed loop",
        )?,
    )?;
    Ok(out)
}
