//! The design tools: PID tuning, H2 synthesis, grey-box identification — what `servo tune`,
//! `servo synth h2` and `servo identify` compute, with the files they write as text.

use crate::config::{built, load};
use crate::servo_err;
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// `servo tune`: the PID with the largest integral gain under `|S| ≤ ms`, `|T| ≤ mt` and a
/// −3 dB bandwidth of at least `bandwidth_hz`, on the exact sampled plant. The report's JSON
/// and the controller fragment (TOML, with the plant it was made for) `servo run -c` takes.
#[pyfunction]
#[pyo3(signature = (bandwidth_hz, ms, mt, config=None, overrides=None))]
pub fn tune(
    py: Python<'_>,
    bandwidth_hz: f64,
    ms: f64,
    mt: f64,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<(String, String)> {
    let loaded = load(config, overrides)?;
    py.detach(|| {
        let plan = built(&loaded)?;
        let r = studies::tune::tune(&plan, bandwidth_hz, ms, mt).map_err(servo_err)?;
        Ok((serde_json::to_string(&r).map_err(servo_err)?, r.to_toml()))
    })
}

/// `servo synth h2`: the discrete H2-optimal controller of the exact sampled plant with its
/// noise models (`thesis_weights`: the §6.3 weighting filters instead), reduced to `order`
/// states if asked, checked in the loop it closes — the controller file (TOML) `servo run
/// --controller ss --ss-file` loads, `(A, B, C, D)`, its H2 norm and the prediction (JSON) of
/// `servo synth h2 --json`, from the same function.
#[pyfunction]
#[pyo3(signature = (effort_weight, thesis_weights, sensor_noise_scale=1.0, order=None, config=None, overrides=None))]
pub fn synth_h2<'py>(
    py: Python<'py>,
    effort_weight: f64,
    thesis_weights: bool,
    sensor_noise_scale: f64,
    order: Option<usize>,
    config: Option<&Bound<'py, PyAny>>,
    overrides: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    use studies::synth::{synthesize, SynthRequest, SynthWeights};
    let loaded = load(config, overrides)?;
    let s = py.detach(|| {
        let plan = built(&loaded)?;
        let weights = if thesis_weights {
            SynthWeights::Thesis { effort_weight }
        } else {
            SynthWeights::Exact {
                effort_weight,
                sensor_noise_scale,
            }
        };
        synthesize(&plan, &SynthRequest { weights, order }).map_err(servo_err)
    })?;
    let d = &s.design;
    let out = crate::models::model(
        py,
        &d.controller,
        1.0 / d.sample_rate_hz,
        &["position_error_v"],
        &["command_v"],
        &format!("H2 controller at {:.0} Hz", d.sample_rate_hz),
    )?;
    out.set_item("controller_toml", d.to_toml())?;
    out.set_item("h2_norm", d.h2_norm)?;
    out.set_item("spectral_radius", d.spectral_radius)?;
    out.set_item(
        "prediction",
        serde_json::to_string(&s.prediction).map_err(servo_err)?,
    )?;
    Ok(out)
}

/// `servo identify`: the grey-box fit of Table 5-2's parameters to a measured FRF
/// (`freq_hz`, complex `measured_m_per_v` — as `servo frf` writes it — or a `frf.csv` path),
/// the report's JSON and the plant file (TOML) it writes.
#[pyfunction]
#[pyo3(signature = (frf, measured_m_per_v=None, config=None, overrides=None))]
pub fn identify(
    py: Python<'_>,
    frf: &Bound<'_, PyAny>,
    measured_m_per_v: Option<PyReadonlyArray1<'_, num_complex::Complex64>>,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<(String, String)> {
    let loaded = load(config, overrides)?;
    let m = measured_frf(frf, measured_m_per_v, None, &loaded, "identify")?;
    py.detach(|| {
        let plan = built(&loaded)?;
        let id = studies::identify::identify_measured(&plan, &m).map_err(servo_err)?;
        Ok((
            serde_json::to_string(&id).map_err(servo_err)?,
            id.model_toml(&plan, &m.source),
        ))
    })
}

/// `servo fit`: a stable rational model of a measured FRF (`freq_hz`, complex
/// `measured_m_per_v` and each bin's 1σ radius `uncertainty_m_per_v` — or a `frf.csv` path as
/// `servo frf` writes it), its order chosen by the uncertainty unless given; the report's JSON
/// (its rational model and the modes the configured plant lacks) and the plant file (TOML) with
/// those modes.
#[pyfunction]
#[pyo3(signature = (frf, measured_m_per_v=None, uncertainty_m_per_v=None, order=None, max_order=30, config=None, overrides=None))]
#[allow(clippy::too_many_arguments)] // Python's keyword arguments
pub fn fit_frd(
    py: Python<'_>,
    frf: &Bound<'_, PyAny>,
    measured_m_per_v: Option<PyReadonlyArray1<'_, num_complex::Complex64>>,
    uncertainty_m_per_v: Option<PyReadonlyArray1<'_, f64>>,
    order: Option<usize>,
    max_order: usize,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<(String, String)> {
    let loaded = load(config, overrides)?;
    let measured = measured_frf(
        frf,
        measured_m_per_v,
        uncertainty_m_per_v,
        &loaded,
        "fit_frd",
    )?;
    py.detach(|| {
        let plan = built(&loaded)?;
        let fit = studies::fit::fit_frf(&plan, &measured, order, max_order).map_err(servo_err)?;
        Ok((
            serde_json::to_string(&fit).map_err(servo_err)?,
            fit.model_toml(&plan, &measured.source),
        ))
    })
}

/// An FRF as `fts_servo.<who>` is given it: a `frf.csv` path (read and checked as `servo`
/// reads it, at the configured rate's Nyquist frequency), or the frequencies in Hz with the
/// complex response (m/V) and optionally each bin's 1σ radius (m/V), of one length.
fn measured_frf(
    frf: &Bound<'_, PyAny>,
    measured_m_per_v: Option<PyReadonlyArray1<'_, num_complex::Complex64>>,
    uncertainty_m_per_v: Option<PyReadonlyArray1<'_, f64>>,
    loaded: &run_config::Loaded,
    who: &str,
) -> PyResult<run_config::frf_file::MeasuredFrf> {
    let Some(g) = measured_m_per_v else {
        let path: PathBuf = frf.extract()?;
        let nyquist_hz = loaded.config.plant.timing.servo_rate_hz / 2.0;
        return run_config::frf_file::read_frf(&path, nyquist_hz).map_err(servo_err);
    };
    let freq_hz: Vec<f64> = frf.extract()?;
    let response = g.as_slice()?.to_vec();
    let uncertainty = match uncertainty_m_per_v {
        Some(u) => Some(u.as_slice()?.to_vec()),
        None => None,
    };
    if response.len() != freq_hz.len()
        || uncertainty
            .as_ref()
            .is_some_and(|u| u.len() != freq_hz.len())
    {
        return Err(pyo3::exceptions::PyValueError::new_err(format!(
            "{who}: the frequencies, the response and the uncertainty differ in length"
        )));
    }
    Ok(run_config::frf_file::MeasuredFrf {
        coherence: vec![1.0; freq_hz.len()],
        freq_hz,
        response,
        uncertainty,
        accel: None,
        source: format!("arrays given to fts_servo.{who}"),
    })
}
