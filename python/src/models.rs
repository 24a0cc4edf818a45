//! The models of a configuration as `(A, B, C, D, dt)` with signal names: python-control
//! takes them as `control.ss(A, B, C, D, dt)` (dt = 0: continuous time).

use crate::arrays::matrix;
use crate::config::plan;
use crate::servo_err;
use loop_model::closed_loop::{self, input, output, ClosedLoop};
use lti::StateSpace;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyTuple};

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
/// `controller`, `loop_gain`, `sensitivity`, `complementary_sensitivity` and `closed_loop`.
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
    let s = p.capa.sensitivity_v_per_m;
    let open = ClosedLoop::open(&plan.sim, s).ok_or_else(|| {
        servo_err("plant.actuator.model = \"coil\" has no exact sampled model: use \"ideal\" or \"second_order\"")
    })?;
    // The open loop's outputs the controller reads carry the contract's names (gap_v,
    // accel_v) and its command input is command_v, so that control.interconnect joins the
    // plant and the controller by name.
    let mut plant_inputs = closed_loop::input::NAMES;
    plant_inputs[input::CONTROL_DISTURBANCE_V] = "command_v";
    let plant_outputs = [
        (output::FOLLOWING_ERROR_M, 1.0, "following_error_m"),
        (output::TRUE_ERROR_M, 1.0, "true_error_m"),
        (output::MEASURED_M, 1.0, "measured_m"),
        (output::TOOL_M, 1.0, "tool_m"),
        (output::MEASURED_M, s, "gap_v"),
        (output::ACCEL_READING_V, 1.0, "accel_v"),
    ];
    let rows: Vec<_> = plant_outputs.iter().map(|&(o, k, _)| (o, k)).collect();
    let plant = open.outputs(&rows);
    let names: Vec<&str> = plant_outputs.iter().map(|x| x.2).collect();
    out.set_item(
        "plant_sampled",
        model(py, &plant, dt, &plant_inputs, &names, "the sampled plant without a controller (exact: zero-order hold, delay, averaging): the DAC command_v in, the readings gap_v and accel_v out (the controller's inputs)")?,
    )?;
    let controller = &plan.controller.linear;
    out.set_item(
        "controller",
        model(
            py,
            &controller.state_space(),
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
        "loop_gain",
        model(
            py,
            &open.loop_gain(controller, s).map_err(servo_err)?,
            dt,
            &["command_v"],
            &["returned_v"],
            "the loop gain L = −K·P broken at the DAC command (negative feedback: the loop is 1 + L; control.margin takes its frequency response)",
        )?,
    )?;
    let cl = &plan.closed_loop;
    for (key, out_row, what) in [
        (
            "sensitivity",
            output::FOLLOWING_ERROR_M,
            "the sensitivity S: reference to following error (thesis eq 5-1)",
        ),
        (
            "complementary_sensitivity",
            output::MEASURED_M,
            "the complementary sensitivity T: reference to measured position (thesis eq 5-2)",
        ),
    ] {
        let sys = cl.subsystem(&[(out_row, 1.0)], input::REFERENCE_M);
        let name = closed_loop::output::NAMES[out_row];
        out.set_item(key, model(py, &sys, dt, &["reference_m"], &[name], what)?)?;
    }
    out.set_item(
        "closed_loop",
        model(
            py,
            &cl.sys,
            dt,
            &closed_loop::input::NAMES,
            &closed_loop::output::NAMES,
            "the sampled closed loop",
        )?,
    )?;
    Ok(out)
}
