//! One closed-loop run: controller (servo-core) against the simulated stage (plant-sim),
//! recorded to MCAP (recorder) off the tick, summarised; and the same summary from a file.

use crate::analysis::ClosedLoop;
use crate::config::{ConfigError, Loaded, RunConfig, Scenario};
use crate::controller::Controller;
use crate::servo_loop::{frame, ServoLoop, SimBackend};
use crate::summary::{RunMeta, Summary, SummaryBuilder};
use daq_io::{Backend, Daq, InProcess};
use plant_sim::model::ModelError;
use plant_sim::params::CurrentLoopModel;
use plant_sim::sim::SimError;
use plant_sim::Simulator;
use recorder::{RecordError, Recorder, WhenFull};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Run errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// Configuration.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The simulator could not be built for another reason.
    #[error("plant: {0}")]
    Plant(String),
    /// The controller and the plant form an unstable loop.
    #[error("the closed loop is unstable (spectral radius {radius:.6} ≥ 1) with {controller}: lower the gains or check the controller file; nothing was run")]
    Unstable {
        /// Largest closed-loop eigenvalue magnitude.
        radius: f64,
        /// Controller description.
        controller: String,
    },
    /// Recording.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// Reading a recording.
    #[error(transparent)]
    Read(#[from] recorder::ReadError),
    /// Writing analysis results.
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
    /// A design step (tuning, synthesis) found no solution.
    #[error(transparent)]
    Tune(#[from] design::tune::TuneError),
    /// The multi-process transport failed.
    #[error("transport: {0}")]
    Transport(String),
    /// The controller lost its plant.
    #[error("{0}; the controller stopped")]
    PlantLost(String),
    /// A recording without the metadata `servo run` writes.
    #[error("{0}: no fts-servo run metadata (was it written by `servo run`?)")]
    NotARun(PathBuf),
}

/// How to run.
pub struct RunOptions<'a> {
    /// Where to record (None: no recording).
    pub out: Option<PathBuf>,
    /// Set to stop early (Ctrl-C); the recording is still finished.
    pub stop: &'a AtomicBool,
    /// Called every few thousand ticks with (done, total).
    pub progress: &'a mut dyn FnMut(u64, u64),
}

/// The facts every summary of a run of `c` shares; the live ones (wall time, recording, HIL)
/// unset.
pub(crate) fn meta(c: &RunConfig, controller: String) -> RunMeta {
    RunMeta {
        servo_rate_hz: c.plant.timing.servo_rate_hz,
        seed: c.run.seed,
        settle_s: c.run.settle(),
        controller,
        scenario: scenario_name(&c.scenario).into(),
        wall_s: None,
        interrupted: false,
        recorded_messages: None,
        dropped_frames: None,
        spectral_radius: None,
        hil: None,
    }
}

fn scenario_name(s: &Scenario) -> &'static str {
    match s {
        Scenario::Hold => "hold",
        Scenario::Sine { .. } => "sine",
        Scenario::Step { .. } => "step",
        Scenario::Chirp { .. } => "chirp",
        Scenario::Machine(_) => "machine",
        Scenario::IntermittentCut { .. } => "intermittent-cut",
    }
}

/// Plant parameter errors located at their `plant.…` key in the config file.
pub(crate) fn plant_error(e: SimError, at: &Loaded) -> RunError {
    match e {
        SimError::Model(ModelError::Parameter { key, value, range }) => {
            at.invalid(&format!("plant.{key}"), value, &range).into()
        }
        other => RunError::Plant(other.to_string()),
    }
}

/// The sampled closed loop of `sim` with `ctrl` (the `coil` current model is linearised as
/// the ideal loop of eq 5-9).
fn closed_loop_of(
    cfg: &Loaded,
    sim: &Simulator,
    ctrl: &Controller,
) -> Result<ClosedLoop, RunError> {
    let c = &cfg.config;
    let linear = match sim.linear_tick() {
        Some(l) => l,
        None => {
            let mut ideal = c.plant;
            ideal.actuator.model = CurrentLoopModel::Ideal;
            Simulator::new(&ideal, 0, &Default::default())
                .map_err(|e| plant_error(e, cfg))?
                .linear_tick()
                .expect("ideal model")
        }
    };
    Ok(ClosedLoop::new(
        &linear,
        &ctrl.linear,
        c.plant.capa.sensitivity_v_per_m,
        sim.period_s(),
    ))
}

/// Gain and phase margins of the loop of `cfg` broken at the actuator input (the sampled
/// plant from DAC command to gap reading, times the controller's gap channel), searched from
/// 1 Hz to Nyquist. Acceleration feedback's inner loop is not part of this break.
pub fn loop_margins(cfg: &Loaded) -> Result<design::loops::Margins, RunError> {
    cfg.config.validate(cfg)?;
    let sim = Simulator::new(&cfg.config.plant, 0, &Default::default())
        .map_err(|e| plant_error(e, cfg))?;
    let ctrl = Controller::build(cfg)?;
    let s = cfg.config.plant.capa.sensitivity_v_per_m;
    let period = sim.period_s();
    let open = ClosedLoop::open(&sim, s)
        .ok_or_else(|| RunError::Plant("margins need the ideal current-loop model".into()))?;
    let k = &ctrl.linear;
    let k_gap = design::lti::StateSpace {
        a: k.a.clone(),
        b: k.b.columns(0, 1).into_owned(),
        c: k.c.clone(),
        d: k.d.columns(0, 1).into_owned(),
    };
    let loop_gain = |f: f64| {
        let p = open.command_response(f).unwrap_or_default() * s;
        let kk = k_gap
            .freq_response_discrete(f, period)
            .map(|m| m[(0, 0)])
            .unwrap_or_default();
        -(kk * p)
    };
    Ok(design::loops::margins(loop_gain, 1.0, 0.499 / period))
}

/// The sampled closed loop a run of `cfg` would have, and the controller's description.
pub fn closed_loop(cfg: &Loaded) -> Result<(ClosedLoop, String), RunError> {
    cfg.config.validate(cfg)?;
    let sim = Simulator::new(&cfg.config.plant, 0, &Default::default())
        .map_err(|e| plant_error(e, cfg))?;
    let ctrl = Controller::build(cfg)?;
    Ok((closed_loop_of(cfg, &sim, &ctrl)?, ctrl.description))
}

/// The spectral radius of `cl`, or [`RunError::Unstable`] when it is ≥ 1.
fn stable(cl: &ClosedLoop, controller: &str) -> Result<f64, RunError> {
    let radius = cl.spectral_radius();
    if radius >= 1.0 {
        return Err(RunError::Unstable {
            radius,
            controller: controller.to_owned(),
        });
    }
    Ok(radius)
}

/// The pre-run check of [`run`] alone: the spectral radius of the sampled loop of `cfg`, or
/// [`RunError::Unstable`].
pub fn check_stable(cfg: &Loaded) -> Result<f64, RunError> {
    let (cl, controller) = closed_loop(cfg)?;
    stable(&cl, &controller)
}

/// Runs `cfg`: builds everything, checks closed-loop stability, runs, records, summarises.
pub fn run(cfg: &Loaded, opts: RunOptions<'_>) -> Result<Summary, RunError> {
    run_with(cfg, opts, |_| {})
}

/// [`run`], showing every recorded frame to `on_frame` as well (analyses that need more than
/// the summary, without reading the file back).
pub fn run_with(
    cfg: &Loaded,
    opts: RunOptions<'_>,
    mut on_frame: impl FnMut(&recorder::Frame),
) -> Result<Summary, RunError> {
    let c = &cfg.config;
    c.validate(cfg)?;
    let backend = SimBackend::for_run(cfg)?;
    let mut servo = ServoLoop::new(cfg)?;
    let description = servo.controller.description.clone();
    let radius = stable(
        &closed_loop_of(cfg, backend.sim(), &servo.controller)?,
        &description,
    )?;
    let mut recorder = match &opts.out {
        Some(path) => Some(Recorder::create(path, metadata(cfg), WhenFull::Wait)?),
        None => None,
    };
    let total = c.ticks();
    let mut summary = SummaryBuilder::new(c.run.settle());
    let start = Instant::now();
    let mut daq = InProcess::new(backend, total);
    let mut truth = daq_io::Truth::default();
    let mut interrupted = false;
    loop {
        let s = daq.read().expect("in-process reads cannot fail");
        if s.seq.is_multiple_of(8192) {
            (opts.progress)(s.seq, total);
            if opts.stop.load(Ordering::Relaxed) && s.flags & daq_io::flags::END == 0 {
                interrupted = true;
                daq.stop();
                continue;
            }
        }
        let (command, telemetry) = servo.tick(&s);
        if let Some(t) = telemetry {
            let frame = frame(&t, &truth);
            summary.add(&frame);
            on_frame(&frame);
            if let Some(rec) = &mut recorder {
                if rec.push(frame).is_err() {
                    // The writer thread failed (disk full…): its error comes out of finish().
                    break;
                }
            }
        }
        let Some(command) = command else { break };
        daq.write(command).expect("in-process writes cannot fail");
        truth = daq.backend().truth().unwrap_or_default();
    }
    (opts.progress)(summary.ticks(), total);
    let wall = start.elapsed().as_secs_f64();
    let stats = match recorder {
        Some(r) => Some(r.finish()?),
        None => None,
    };
    Ok(summary.finish(RunMeta {
        wall_s: Some(wall),
        interrupted,
        recorded_messages: stats.map(|s| s.messages),
        dropped_frames: stats.map(|s| s.dropped_frames),
        spectral_radius: Some(radius),
        ..meta(c, description)
    }))
}

/// [`run`] to the end of `cfg`'s duration: no recording, no progress, no stop flag (sweeps,
/// tests, benches).
pub fn run_to_end(cfg: &Loaded) -> Result<Summary, RunError> {
    run_to_end_with(cfg, |_| {})
}

/// [`run_to_end`], showing every frame to `on_frame` (see [`run_with`]).
pub fn run_to_end_with(
    cfg: &Loaded,
    on_frame: impl FnMut(&recorder::Frame),
) -> Result<Summary, RunError> {
    let stop = AtomicBool::new(false);
    run_with(
        cfg,
        RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
        },
        on_frame,
    )
}

/// Metadata written into the recording.
pub(crate) fn metadata(cfg: &Loaded) -> BTreeMap<String, String> {
    let c = &cfg.config;
    BTreeMap::from([
        ("config".to_string(), c.to_toml()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("seed".to_string(), c.run.seed.to_string()),
        (
            "servo_rate_hz".to_string(),
            c.plant.timing.servo_rate_hz.to_string(),
        ),
        ("settle_s".to_string(), c.run.settle().to_string()),
    ])
}

/// A recording written by [`run`] and the configuration it was run with.
pub fn read_run(path: &Path) -> Result<(Loaded, recorder::Recording), RunError> {
    let rec = recorder::read(path)?;
    let text = rec
        .metadata
        .get("config")
        .ok_or_else(|| RunError::NotARun(path.to_owned()))?;
    let cfg: RunConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    Ok((
        Loaded {
            config: cfg,
            ..Default::default()
        },
        rec,
    ))
}

/// Recomputes the summary of a recording written by [`run`].
pub fn inspect(path: &Path) -> Result<Summary, RunError> {
    let (loaded, rec) = read_run(path)?;
    Ok(summarise(&loaded, &rec))
}

/// The summary of the recording `rec` of a run of `loaded`.
pub fn summarise(loaded: &Loaded, rec: &recorder::Recording) -> Summary {
    let cfg = &loaded.config;
    let mut b = SummaryBuilder::new(cfg.run.settle());
    rec.frames.iter().for_each(|f| b.add(f));
    let controller = Controller::build(loaded)
        .map(|c| c.description)
        .unwrap_or_else(|_| format!("{:?}", cfg.controller.kind));
    let expected = cfg.ticks();
    b.finish(RunMeta {
        interrupted: (rec.frames.len() as u64) < expected,
        recorded_messages: Some(rec.messages),
        ..meta(cfg, controller)
    })
}
