//! `run_hil` and `qualify_host`: a HIL run of three `servo` processes and a host qualification,
//! through the library calls `servo run --hil` and `servo latency` make.

use crate::config::{built, load};
use crate::servo_err;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use runner::config::{RealtimeConfig, Role};
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
