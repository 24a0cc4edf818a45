//! `fts_servo._native`: the Rust side of the `fts_servo` Python package. The Python layer
//! (`python/fts_servo/__init__.py`) gives these functions their documented signatures; every
//! error is a `fts_servo.ServoError` carrying the same located message the `servo` CLI prints.

use pyo3::prelude::*;

mod arrays;
mod config;
mod design_api;
mod hil_api;
mod loop_api;
mod models;
mod optics_api;
mod recording;
mod replay_api;
mod simulate;
mod studies_api;
mod study_api;

pyo3::create_exception!(
    _native,
    ServoError,
    pyo3::exceptions::PyException,
    "An fts-servo error: bad input (with the file, key and allowed range), an unstable loop, \
     an unreadable recording."
);

/// Any displayable error as a [`ServoError`] with its message.
pub(crate) fn servo_err(e: impl std::fmt::Display) -> PyErr {
    ServoError::new_err(e.to_string())
}

/// The module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ServoError", m.py().get_type::<ServoError>())?;
    m.add_class::<loop_api::Servo>()?;
    m.add_class::<loop_api::Plant>()?;
    m.add_function(wrap_pyfunction!(simulate::run, m)?)?;
    m.add_function(wrap_pyfunction!(hil_api::run_hil, m)?)?;
    m.add_function(wrap_pyfunction!(hil_api::qualify_host, m)?)?;
    m.add_function(wrap_pyfunction!(hil_api::control, m)?)?;
    m.add_function(wrap_pyfunction!(replay_api::replay, m)?)?;
    m.add_function(wrap_pyfunction!(config::resolved_config, m)?)?;
    m.add_function(wrap_pyfunction!(models::models, m)?)?;
    m.add_function(wrap_pyfunction!(studies_api::budget, m)?)?;
    m.add_function(wrap_pyfunction!(studies_api::loop_response, m)?)?;
    m.add_function(wrap_pyfunction!(recording::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(design_api::tune, m)?)?;
    m.add_function(wrap_pyfunction!(design_api::synth_h2, m)?)?;
    m.add_function(wrap_pyfunction!(design_api::identify, m)?)?;
    m.add_function(wrap_pyfunction!(design_api::fit_frd, m)?)?;
    m.add_function(wrap_pyfunction!(optics_api::prescription_sag, m)?)?;
    m.add_function(wrap_pyfunction!(optics_api::read_map, m)?)?;
    m.add_function(wrap_pyfunction!(study_api::study_info, m)?)?;
    m.add_function(wrap_pyfunction!(study_api::study_rows, m)?)?;
    m.add_function(wrap_pyfunction!(study_api::study_open, m)?)?;
    m.add_function(wrap_pyfunction!(study_api::study_finish, m)?)?;
    Ok(())
}
