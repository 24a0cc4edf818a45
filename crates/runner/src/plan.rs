//! A run resolved once: the configuration validated, relative paths resolved against the
//! config file's folder, the surface and the controller file loaded, and the simulator, the
//! controller, the sampled closed loop and the feedforward built. Everything at run time (the
//! in-process loop, each HIL process, every study) is built from a [`Plan`], never from the
//! raw configuration.

use crate::error::RunError;
use crate::recorded_deployment;
pub use crate::recorded_deployment::DEPLOYMENT_INPUT;
use crate::repetitive::RepetitivePlan;
use crate::run_input::input_or_read;
use loop_model::closed_loop::ClosedLoop;
use loop_model::controller::{stage_of, RunController};
use loop_model::feedforward::{feedforward_spec, FirFit};
use loop_model::measured_loop::MeasuredLoop;
use plant_sim::params::CurrentLoopModel;
use plant_sim::Simulator;
use recorder::Input;
use run_config::input_file::read_text;
use run_config::surface::LoadedSurface;
use run_config::SimBackend;
use run_config::{
    check_made_for, made_for_plant, ConfigError, ControllerConfig, ControllerKind, Loaded, Origin,
    RunConfig, Scenario, SurfaceConfig,
};
use servo_config::{Deployment, Invalid, ReferenceSpec, SsMatrices};

/// Attachment name of the controller file in a recording.
pub const CONTROLLER_INPUT: &str = "controller.toml";
/// Attachment name of the measured FRF (`controller.frf_file`) in a recording.
pub const FRF_INPUT: &str = "frf.csv";
/// Attachment name of the surface image in a recording.
pub const SURFACE_INPUT: &str = "surface.png";

/// Attachment name of a surface prescription in a recording (resolved to SI, grid included).
pub const PRESCRIPTION_INPUT: &str = "prescription.json";

/// A run, resolved and built.
#[derive(Clone)]
pub struct Plan {
    /// The validated configuration; `controller.ss_file` and image paths are absolute or
    /// relative to the working directory (resolved against the config file's folder).
    pub config: RunConfig,
    /// Where the configuration came from (for located errors).
    pub origin: Origin,
    /// The simulated stage at tick 0 (seeded, with the scenario's cutting profile).
    pub sim: Simulator,
    /// The controller: what the runtime runs, and its linear model.
    pub controller: RunController,
    /// The sampled closed loop of `sim` and `controller` (a `coil` current loop linearised as
    /// the ideal loop of eq 5-9).
    pub closed_loop: ClosedLoop,
    /// The machined surface, for a machining scenario.
    pub surface: Option<LoadedSurface>,
    /// Everything the runtime's `Servo` runs (the feedforward designed, the stability range
    /// not yet computed: [`crate::gain_range::checked`] adds it).
    pub deployment: Deployment,
    /// The files the run read (controller file, surface image), to embed in its recording.
    pub inputs: Vec<Input>,
    /// The repetitive controller of a machining run, checked on the closed loop.
    pub repetitive: Option<RepetitivePlan>,
    /// The loop closed on the measured FRF `controller.frf_file`, when the run names one.
    pub measured: Option<MeasuredLoop>,
    /// The FIR feedforward's fit, for `feedforward = "fir"`.
    pub fir: Option<FirFit>,
    /// For a plan rebuilt from a recording that carries its deployment ([`DEPLOYMENT_INPUT`]),
    /// which [`Plan::deployment`] then is: the largest relative difference between the
    /// recorded numbers and those designed here (0: the same bits; a processor with other
    /// vector instructions rounds the eigenvalue-based designs in the last bits; infinite:
    /// another form, a recording from another version of the design).
    pub design_difference: Option<f64>,
}

impl Plan {
    /// Validates and builds the run of `loaded`, reading the files it names.
    pub fn new(loaded: &Loaded) -> Result<Self, RunError> {
        Self::with_inputs(loaded, Vec::new())
    }

    /// Validates and builds the run of `loaded`, taking the input files it names (controller
    /// file, surface image) from `inputs` by attachment name where there ([`CONTROLLER_INPUT`],
    /// [`SURFACE_INPUT`]) — a recording's embedded copies — and reading the others. A recorded
    /// deployment among them ([`DEPLOYMENT_INPUT`]) is what the plan runs (its configuration
    /// must be the recording's: see [`Plan::design_difference`]).
    pub fn with_inputs(loaded: &Loaded, mut inputs: Vec<Input>) -> Result<Self, RunError> {
        let origin = loaded.origin.clone();
        let r = run_config::resolve(loaded, |s| surface_file(s, &origin, &mut inputs))?;
        Plan::assemble(r.config, origin, r.sim, r.surface, inputs)
    }

    /// The same run with another controller (the stage, its noise and the surface reused;
    /// a controller file path is taken as it is, like the plan's own resolved paths, and the
    /// file already read is reused when the path is unchanged).
    pub fn with_controller(&self, controller: ControllerConfig) -> Result<Self, RunError> {
        self.with_controller_file(controller, None)
    }

    /// [`Plan::with_controller`] whose controller file (for `ss`) is `file`'s bytes, not read
    /// from disk (a controller sent to a running loop).
    pub fn with_controller_file(
        &self,
        controller: ControllerConfig,
        file: Option<Vec<u8>>,
    ) -> Result<Self, RunError> {
        let same_file = file.is_none() && controller.ss_file == self.config.controller.ss_file;
        let mut config = self.config.clone();
        config.controller = controller;
        config.validate(&self.origin)?;
        let mut inputs: Vec<Input> = self
            .inputs
            .iter()
            .filter(|i| same_file || i.name != CONTROLLER_INPUT)
            .filter(|i| i.name != DEPLOYMENT_INPUT)
            .cloned()
            .collect();
        if let Some(data) = file {
            inputs.push(Input {
                name: CONTROLLER_INPUT.into(),
                media_type: "application/toml".into(),
                data,
            });
        }
        Plan::assemble(
            config,
            self.origin.clone(),
            self.sim.clone(),
            self.surface.clone(),
            inputs,
        )
    }

    /// The same run for `duration_s` seconds of simulated time (everything else reused).
    pub fn with_duration(&self, duration_s: f64) -> Result<Self, RunError> {
        let mut plan = self.clone();
        plan.config.run.duration_s = duration_s;
        plan.config.validate(&plan.origin)?;
        Ok(plan)
    }

    fn assemble(
        config: RunConfig,
        origin: Origin,
        sim: Simulator,
        surface: Option<LoadedSurface>,
        mut inputs: Vec<Input>,
    ) -> Result<Self, RunError> {
        let c = &config.controller;
        let run = made_for_plant(&config.plant);
        if let Some(made_for) = &c.made_for {
            check_made_for(made_for, &run, &origin, "controller.made_for", c.force)?;
        }
        let ss = match (&c.kind, &c.ss_file) {
            (ControllerKind::Ss, Some(path)) => {
                let bytes =
                    input_or_read(&mut inputs, CONTROLLER_INPUT, "application/toml", || {
                        read_text(path).map(String::into_bytes)
                    })?;
                let text = String::from_utf8_lossy(&bytes);
                Some(read_ss_file(&text, path, &config, &run)?)
            }
            _ => {
                inputs.retain(|i| i.name != CONTROLLER_INPUT);
                None
            }
        };
        let controller = RunController::build(&config, &origin, ss)?;
        let closed_loop = closed_loop_of(&config, &origin, &sim, &controller)?;
        if let Some(seed) = config.run.practice_seed {
            // Drawn here so that a run on it cannot fail later (its stage draws it again).
            run_config::practice_stage(&config, &origin, seed)?;
        }
        let measured = measured_loop(&config, &sim, &controller, &mut inputs)?;
        let (feedforward, fir) = feedforward_spec(&config, &closed_loop, measured.as_ref())?;
        let mut deployment = Deployment {
            servo_rate_hz: config.plant.timing.servo_rate_hz,
            stage: stage_of(&config),
            controller: controller.spec.clone(),
            stability: None,
            reference: config
                .scenario
                .reference(config.run.duration_s)
                .unwrap_or(ReferenceSpec::Hold),
            feedforward,
            smoothing_hz: config.controller.smoothing_hz,
            protection: config.protection,
        };
        deployment
            .check()
            .map_err(|e| located_in_run(&e, &origin))?;
        let design_difference = match inputs.iter().position(|i| i.name == DEPLOYMENT_INPUT) {
            Some(at) => Some(recorded_deployment::adopt(
                &mut deployment,
                &inputs.remove(at).data,
            )?),
            None => None,
        };
        inputs.push(recorded_deployment::embedded(&deployment));
        let repetitive = match &config.scenario {
            Scenario::Machine(m) => match &m.repetitive {
                Some(s) => Some(crate::repetitive::plan(
                    &config,
                    m,
                    s,
                    &closed_loop,
                    measured.as_ref(),
                    &deployment,
                    &origin,
                    &mut inputs,
                )?),
                None => None,
            },
            _ => None,
        };
        if repetitive.is_none() {
            inputs.retain(|i| i.name != crate::repetitive::TABLE_INPUT);
        }
        Ok(Plan {
            config,
            origin,
            sim,
            controller,
            closed_loop,
            surface,
            deployment,
            inputs,
            repetitive,
            measured,
            fir,
            design_difference,
        })
    }

    /// The spectral radius of the sampled closed loop, or [`RunError::Unstable`] when it is
    /// ≥ 1 or not a number (coefficients that overflow; the pre-run check of every run and of
    /// every HIL process); with a measured FRF ([`Plan::measured`]),
    /// [`RunError::UnstableOnMeasured`] when the loop on it, or any within its uncertainty
    /// disks, is not stable.
    pub fn check_stable(&self) -> Result<f64, RunError> {
        let radius = self.closed_loop.spectral_radius();
        if radius.is_nan() || radius >= 1.0 {
            return Err(RunError::Unstable {
                radius,
                controller: self.controller.description.clone(),
            });
        }
        if let Some(m) = &self.measured {
            let v = m.stability.verdict;
            if v.robustly_stable() {
                return Ok(radius);
            }
            return Err(RunError::UnstableOnMeasured {
                frf: m.source.clone(),
                stable: v.stable,
                distance: v.disk_distance.0,
                at_hz: v.disk_distance.1,
                controller: self.controller.description.clone(),
            });
        }
        Ok(radius)
    }

    /// Servo ticks in the run.
    pub fn ticks(&self) -> u64 {
        self.config.ticks()
    }

    /// Servo period in s.
    pub fn period_s(&self) -> f64 {
        self.config.plant.period_s()
    }

    /// The simulated stage of this run as a daq-io backend: its seeded simulator (or the
    /// practice stage), the scenario's cutting profile and the part of a machining scenario.
    pub fn stage(&self) -> SimBackend {
        SimBackend::for_run(
            &self.config,
            &self.origin,
            self.sim.clone(),
            self.surface.clone(),
        )
        .expect("the plan drew this stage without error")
    }
}

/// The loop closed on the measured FRF `controller.frf_file` (taken from `inputs` where a
/// recording holds it, else read and added there); None when the run names none.
fn measured_loop(
    config: &RunConfig,
    sim: &Simulator,
    controller: &RunController,
    inputs: &mut Vec<Input>,
) -> Result<Option<MeasuredLoop>, RunError> {
    let Some(path) = &config.controller.frf_file else {
        inputs.retain(|i| i.name != FRF_INPUT);
        return Ok(None);
    };
    let bytes = input_or_read(inputs, FRF_INPUT, "text/csv", || {
        run_config::input_file::read_input(path, run_config::input_file::MAX_TEXT_BYTES)
    })?;
    let nyquist = config.plant.timing.servo_rate_hz / 2.0;
    let frf = run_config::frf_file::parse_frf(&bytes, path, nyquist)?;
    let sensitivity = config.plant.capa.sensitivity_v_per_m;
    let open = ClosedLoop::open(sim, sensitivity).ok_or(RunError::NeedsLinearPlant {
        what: "a design on a measured FRF",
    })?;
    Ok(Some(MeasuredLoop::new(
        &frf,
        &open,
        &controller.linear,
        sensitivity,
    )?))
}

/// The state-space controller file `text` named by `controller.ss_file` (at `path`): its
/// matrices, checked for shape, finiteness, the run's servo rate and — when it says what it was
/// made for — the run's plant (`run`), unless `controller.force`.
fn read_ss_file(
    text: &str,
    path: &std::path::Path,
    config: &RunConfig,
    run: &servo_config::MadeFor,
) -> Result<SsMatrices, ConfigError> {
    let at = Origin {
        path: Some(path.to_owned()),
        text: Some(text.to_owned()),
    };
    let running = config.controller.spec(None);
    let f = servo_config::parse_controller_file(text, &at, &running)?;
    f.check_rate(
        config.plant.timing.servo_rate_hz,
        &at,
        "the run's plant.timing.servo_rate_hz",
    )?;
    if let Some(made_for) = &f.made_for {
        check_made_for(made_for, run, &at, "made_for", config.controller.force)?;
    }
    f.spec.ss.ok_or_else(|| {
        at.invalid(
            "a",
            "(a [controller] table)",
            "a state-space controller file (sample_rate_hz, a, b, c, d) for controller.ss_file",
        )
    })
}

/// A deployment value out of range, at the key of the run configuration it came from.
pub fn located_in_run(e: &Invalid, at: &Origin) -> ConfigError {
    let e = match (e.section, e.key) {
        ("", "smoothing_hz") => e.in_section("controller"),
        ("reference", _) => e.in_section("scenario"),
        _ => *e,
    };
    at.located(&e)
}

/// The bytes of the file `surface` names: the recording's embedded copy from `inputs` when
/// there ([`SURFACE_INPUT`], [`PRESCRIPTION_INPUT`]), else read (an image as it is, a
/// prescription resolved to SI with its grid, as JSON) and added to `inputs`.
fn surface_file(
    surface: &SurfaceConfig,
    origin: &Origin,
    inputs: &mut Vec<Input>,
) -> Result<Option<Vec<u8>>, ConfigError> {
    let name = match surface {
        SurfaceConfig::Image { .. } => SURFACE_INPUT,
        SurfaceConfig::Prescription { .. } => PRESCRIPTION_INPUT,
        _ => return Ok(None),
    };
    if let Some(i) = inputs.iter().find(|i| i.name == name) {
        return Ok(Some(i.data.clone()));
    }
    let Some(file) = run_config::surface_file(surface, origin)? else {
        return Ok(None);
    };
    inputs.push(Input {
        name: name.into(),
        media_type: file.media_type.into(),
        data: file.bytes.clone(),
    });
    Ok(Some(file.bytes))
}

/// The exact linear tick of `sim` (the `coil` current model is linearised as the ideal loop
/// of eq 5-9).
pub fn linear_tick_of(
    config: &RunConfig,
    at: &Origin,
    sim: &Simulator,
) -> Result<plant_sim::LinearTick, RunError> {
    Ok(match sim.linear_tick() {
        Some(l) => l,
        None => {
            let mut ideal = config.plant;
            ideal.actuator.model = CurrentLoopModel::Ideal;
            Simulator::new(&ideal, 0, &Default::default())
                .map_err(|e| run_config::plant_error(e, at))?
                .linear_tick()
                .expect("ideal model")
        }
    })
}

/// The sampled closed loop of `sim` with `ctrl`.
fn closed_loop_of(
    config: &RunConfig,
    at: &Origin,
    sim: &Simulator,
    ctrl: &RunController,
) -> Result<ClosedLoop, RunError> {
    Ok(ClosedLoop::new(
        &linear_tick_of(config, at, sim)?,
        &ctrl.linear,
        config.plant.capa.sensitivity_v_per_m,
        sim.period_s(),
    ))
}
