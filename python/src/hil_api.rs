//! `run_hil` and `qualify_host`: a HIL run of three `servo` processes and a host qualification,
//! through the library calls `servo run --hil` and `servo latency` make.

use crate::config::{built, load};
use crate::servo_err;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use run_config::{RealtimeConfig, Role};
use runner::hil::{supervise, Supervision};
use runner::recording::Target;
use runner::stall::{Measurement, Qualification};
use runner::stop::StopRequest;
use std::path::PathBuf;

/// Runs the configuration as plant, controller and recorder processes of the `servo` binary
/// at `servo` (in lockstep, or paced by the wall clock with `realtime`), recording to `out`
/// (None: not recorded), and returns the recorder's summary as JSON. A process that fails
/// raises ServoError naming it and its exit code.
#[pyfunction]
#[pyo3(signature = (servo, config=None, overrides=None, out=None, overwrite=false, prefix=None, realtime=false))]
#[allow(clippy::too_many_arguments)] // the Python keywords, each documented
pub fn run_hil(
    py: Python<'_>,
    servo: PathBuf,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
    out: Option<PathBuf>,
    overwrite: bool,
    prefix: Option<String>,
    realtime: bool,
) -> PyResult<String> {
    let loaded = load(config, overrides)?;
    let supervision = Supervision {
        servo,
        prefix,
        realtime,
        peer_timeout_ms: None,
        out: out.map(|path| Target {
            overwrite,
            ..Target::new(path)
        }),
    };
    // Without the GIL: other Python threads run meanwhile. Python's own Ctrl-C handling stays
    // as it is; the run ends when its processes do.
    let run = py.detach(|| {
        let plan = built(&loaded)?;
        supervise(&plan, &supervision, &StopRequest::new(), &mut |_, _| {}).map_err(servo_err)
    })?;
    if let Some(f) = run.failed {
        return Err(servo_err(format!(
            "servo {} exited with {}",
            f.process, f.code
        )));
    }
    serde_json::to_string(&run.summary).map_err(servo_err)
}

/// Measures this host's pacing at `rate_hz` (default: the configuration's loop rate) for
/// `duration_s` with the configuration's `[realtime]` settings (the plant's, as `servo latency`
/// measures) and judges the configuration's loop against it; returns the qualification as the
/// JSON `servo latency --json` writes.
#[pyfunction]
#[pyo3(signature = (config=None, overrides=None, rate_hz=None, duration_s=5.0))]
pub fn qualify_host(
    py: Python<'_>,
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
    rate_hz: Option<f64>,
    duration_s: f64,
) -> PyResult<String> {
    let loaded = load(config, overrides)?;
    let realtime: RealtimeConfig = loaded.config.realtime;
    let m = Measurement {
        rate_hz: rate_hz.unwrap_or(loaded.config.plant.timing.servo_rate_hz),
        duration_s,
        realtime,
        role: Role::Plant,
    };
    let q = py.detach(|| Qualification::measure(&loaded, &m, &mut |_, _| {}).map_err(servo_err))?;
    serde_json::to_string(&q).map_err(servo_err)
}

/// Sends one control-plane request to the run on `prefix` — `"start"`, `"stop"`, `"gain"`
/// (with `value`, a dimensionless scale) or `"load"` (with `file`, a controller file) — and
/// returns what the run did in the words `servo ctl` prints; a refusal raises ServoError.
#[pyfunction]
#[pyo3(signature = (prefix, request, value=None, file=None, timeout_s=5.0))]
pub fn control(
    py: Python<'_>,
    prefix: String,
    request: &str,
    value: Option<f64>,
    file: Option<PathBuf>,
    timeout_s: f64,
) -> PyResult<String> {
    use daq_io::control_client::{
        gain_outcome, load_outcome, plant_outcome, request as ask, Request,
    };
    if !(timeout_s > 0.0 && timeout_s <= 60.0) {
        return Err(servo_err(format!(
            "timeout_s = {timeout_s}: allowed (0, 60] s"
        )));
    }
    let r = match (request, value, &file) {
        ("start", None, None) => Request::Start,
        ("stop", None, None) => Request::Stop,
        ("gain", Some(v), None) => Request::Gain(v),
        ("load", None, Some(f)) => Request::Load(
            run_config::input_file::read_input(f, daq_io::MAX_LOAD_BYTES as u64)
                .map_err(servo_err)?,
        ),
        _ => return Err(servo_err(
            "request: \"start\", \"stop\", \"gain\" with value=SCALE, or \"load\" with file=PATH",
        )),
    };
    let ack = py.detach(|| {
        daq_io::ipc::check_prefix(&prefix)
            .map_err(|e| servo_err(format!("prefix {prefix:?}: {e}")))?;
        let ep = daq_io::ipc::Endpoint::open(&prefix, &format!("py-{}", std::process::id()))
            .map_err(servo_err)?;
        ask(
            &ep,
            &prefix,
            &r,
            std::time::Duration::from_secs_f64(timeout_s),
        )
        .map_err(servo_err)
    })?;
    let outcome = match (&r, &file) {
        (Request::Gain(v), _) => gain_outcome(*v, &ack),
        (Request::Load(_), Some(f)) => load_outcome(
            &f.display().to_string(),
            &ack,
            &run_config::describe_made_for(f).unwrap_or_else(|| "its made_for".into()),
        ),
        _ => Ok(plant_outcome(&r, &ack)),
    };
    outcome.map_err(servo_err)
}
