//! Python tick by tick: the runtime's front door (`fts_servo.Servo`) and the simulated stage
//! (`fts_servo.Plant`) as classes — for trying a controller idea in a notebook before writing it
//! in Rust or C. Each call crosses into Python: a few µs a tick, far from real time.

use crate::config::{built, load};
use crate::servo_err;
use daq_io::{Backend, Sensor};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use run_config::SimBackend;
use servo_runtime::Servo as Runtime;

/// The controller a daemon embeds, from a deployment (`servo deploy`).
#[pyclass(module = "fts_servo._native", name = "Servo", unsendable)]
pub struct Servo {
    servo: Runtime,
}

#[pymethods]
impl Servo {
    /// The loop of the deployment file `path` (or, with `text=True`, of the TOML text `path`).
    #[new]
    #[pyo3(signature = (path, text=false))]
    fn new(path: &str, text: bool) -> PyResult<Self> {
        let servo = if text {
            Runtime::from_toml(path)
        } else {
            Runtime::from_file(path)
        }
        .map_err(servo_err)?;
        Ok(Servo { servo })
    }

    /// One tick: the sample's `seq`, gap and accelerometer readings (V), spindle encoder
    /// count and flags in, the command (V) and its flags out.
    #[pyo3(signature = (seq, gap_v, accel_v=0.0, encoder_count=0, flags=0, time_s=0.0))]
    fn tick(
        &mut self,
        seq: u64,
        gap_v: f64,
        accel_v: f64,
        encoder_count: u64,
        flags: u32,
        time_s: f64,
    ) -> (f64, u32) {
        let c = self.servo.tick(&Sensor {
            seq,
            time_s,
            gap_v,
            accel_v,
            encoder_count,
            flags,
            ..Default::default()
        });
        (c.dac_v, c.flags)
    }

    /// The last tick's telemetry as a dict (SI units), or None before the first tick.
    fn telemetry<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(t) = self.servo.telemetry() else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("seq", t.seq)?;
        d.set_item("time_s", t.time_s)?;
        d.set_item("reference_m", t.reference_m)?;
        d.set_item("measured_m", t.measured_m)?;
        d.set_item("following_error_m", t.following_error_m)?;
        d.set_item("controller_error_m", t.controller_error_m)?;
        d.set_item("control_v", t.control_v)?;
        d.set_item("accel_m_s2", t.accel_m_s2)?;
        d.set_item("flags", t.flags)?;
        Ok(Some(d))
    }

    /// What the loop has done: ticks, trip (cause name and tick, or None), the output scale,
    /// saturated ticks, handovers, trips.
    fn status<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = self.servo.status();
        let d = PyDict::new(py);
        d.set_item("ticks", s.ticks)?;
        d.set_item("trip", s.trip.map(|t| (t.cause.name(), t.tick)))?;
        d.set_item("gain_scale", s.gain_scale)?;
        d.set_item("saturated_ticks", s.saturated_ticks)?;
        d.set_item("handovers", s.handovers)?;
        d.set_item("trips", s.trips)?;
        Ok(d)
    }

    /// Scales the output by `scale` (refused outside the checked range: ServoError).
    fn set_gain(&mut self, scale: f64) -> PyResult<()> {
        self.servo.set_gain(scale).map_err(servo_err)
    }

    /// Re-arms the loop after a trip.
    fn reset(&mut self) {
        self.servo.reset();
    }

    /// Loads a controller file's bytes into the running loop (checked; ServoError if refused).
    fn load(&mut self, file: &[u8]) -> PyResult<()> {
        self.servo.load(file).map_err(servo_err)
    }
}

/// The simulated stage of a run configuration, one tick at a time.
#[pyclass(module = "fts_servo._native", name = "Plant", unsendable)]
pub struct Plant {
    stage: SimBackend,
    seq: u64,
    ticks: u64,
}

#[pymethods]
impl Plant {
    /// The seeded stage of `config` with `overrides` (as `fts_servo.run` takes them).
    #[new]
    #[pyo3(signature = (config=None, overrides=None))]
    fn new(
        config: Option<&Bound<'_, PyAny>>,
        overrides: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let plan = built(&load(config, overrides)?)?;
        Ok(Plant {
            stage: plan.stage(),
            seq: 0,
            ticks: plan.ticks(),
        })
    }

    /// The run's ticks (its duration at its servo rate).
    #[getter]
    fn ticks(&self) -> u64 {
        self.ticks
    }

    /// The reading before the first command: (seq, time_s, gap_v, accel_v, encoder_count,
    /// flags).
    fn initial(&mut self) -> (u64, f64, f64, f64, u64, u32) {
        self.seq = 0;
        sample(0, &self.stage.initial())
    }

    /// Holds `dac_v` (V) for one tick; the reading at its end, as `initial` gives it.
    fn step(&mut self, dac_v: f64) -> (u64, f64, f64, f64, u64, u32) {
        self.seq += 1;
        sample(self.seq, &self.stage.step(dac_v))
    }
}

fn sample(seq: u64, s: &Sensor) -> (u64, f64, f64, f64, u64, u32) {
    (seq, s.time_s, s.gap_v, s.accel_v, s.encoder_count, s.flags)
}
