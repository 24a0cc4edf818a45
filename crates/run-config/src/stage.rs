//! The stage a run configuration describes, built from it: the seeded simulator with its plant
//! errors at their `plant.…` keys, the bytes of the surface a machining scenario names, and the
//! whole simulated stage as `servo run` steps it — what the run planner and libfts_plant share.

use crate::sim_backend::SimBackend;
use crate::surface::LoadedSurface;
use crate::SurfaceConfig;
use crate::{input_file, read_prescription, ConfigError, Loaded, Origin, RunConfig, Scenario};
use plant_sim::model::ModelError;
use plant_sim::sim::SimError;
use plant_sim::Simulator;

/// Why a run's stage cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum StageError {
    /// A configuration value outside its range, or a file that cannot be read (named).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The simulator could not be built (a cutting profile it cannot apply; parameter errors
    /// are [`StageError::Config`] at their key).
    #[error("plant: {0}")]
    Sim(SimError),
}

/// A simulator error: a plant parameter out of range at its `plant.…` key in `at`'s file.
pub fn plant_error(e: SimError, at: &Origin) -> StageError {
    match e {
        SimError::Model(ModelError::Parameter { key, value, range }) => {
            at.invalid(&format!("plant.{key}"), value, &range).into()
        }
        other => StageError::Sim(other),
    }
}

/// The seeded simulator of `config` (its plant, `run.seed` and the scenario's cutting profile).
pub fn simulator(config: &RunConfig, at: &Origin) -> Result<Simulator, StageError> {
    Simulator::new(&config.plant, config.run.seed, &config.scenario.cutting())
        .map_err(|e| plant_error(e, at))
}

/// A surface's file as a run embeds it in its recording.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceFile {
    /// The bytes: an image as it is, a prescription resolved to SI with its grid, as JSON.
    pub bytes: Vec<u8>,
    /// `image/png` or `application/json`.
    pub media_type: &'static str,
}

/// The file the surface `surface` names, read (None: a surface that names no file). Its path
/// is taken as it is (resolved against the configuration's folder beforehand).
pub fn surface_file(
    surface: &SurfaceConfig,
    at: &Origin,
) -> Result<Option<SurfaceFile>, ConfigError> {
    Ok(Some(match surface {
        SurfaceConfig::Image { path, .. } => {
            let bytes = input_file::read_input(path, input_file::MAX_IMAGE_BYTES).map_err(|e| {
                at.invalid(
                    "scenario.surface.path",
                    path.display(),
                    &format!("a readable PNG file ({e})"),
                )
            })?;
            SurfaceFile {
                bytes,
                media_type: "image/png",
            }
        }
        SurfaceConfig::Prescription { path, .. } => {
            let p = read_prescription(path)?;
            let bytes = serde_json::to_vec(&p)
                .map_err(|e| at.invalid("scenario.surface.path", path.display(), &e.to_string()))?;
            SurfaceFile {
                bytes,
                media_type: "application/json",
            }
        }
        _ => return Ok(None),
    }))
}

/// A run's configuration with its values checked and its paths resolved against its file's
/// folder, and what its stage is built from.
#[derive(Debug, Clone)]
pub struct Resolved {
    /// The configuration.
    pub config: RunConfig,
    /// Its seeded simulator, with the scenario's cutting profile.
    pub sim: Simulator,
    /// The surface of a machining scenario.
    pub surface: Option<LoadedSurface>,
}

/// Checks the configuration of `loaded`, resolves its paths and builds its simulator and
/// surface; `surface_bytes` gives the bytes of the file a surface names (None: it names none).
pub fn resolve<F>(loaded: &Loaded, mut surface_bytes: F) -> Result<Resolved, StageError>
where
    F: FnMut(&SurfaceConfig) -> Result<Option<Vec<u8>>, ConfigError>,
{
    let at = &loaded.origin;
    let mut config = loaded.config.clone();
    config.validate(at)?;
    config.resolve_paths(at);
    let sim = simulator(&config, at)?;
    let surface = match &config.scenario {
        Scenario::Machine(m) => {
            let file = surface_bytes(&m.surface)?;
            Some(LoadedSurface::load(m, at, file.as_deref())?)
        }
        _ => None,
    };
    Ok(Resolved {
        config,
        sim,
        surface,
    })
}

/// The simulated stage of the run `loaded`, as `servo run` steps it ([`resolve`]d, its surface
/// read from disk): the seeded simulator (or the practice stage of `run.practice_seed`), the
/// scenario's cutting profile and the part of a machining scenario.
pub fn simulated_stage(loaded: &Loaded) -> Result<SimBackend, StageError> {
    let at = &loaded.origin;
    let r = resolve(loaded, |s| Ok(surface_file(s, at)?.map(|f| f.bytes)))?;
    Ok(SimBackend::for_run(&r.config, at, r.sim, r.surface)?)
}
