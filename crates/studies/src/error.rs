//! What can make a study fail, naming the part that failed.

use run_config::ConfigError;
use runner::RunError;
use std::path::PathBuf;

/// Study errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum StudyError {
    /// Configuration or a study parameter out of range (file, key, allowed range).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Building or running the loop.
    #[error(transparent)]
    Run(#[from] RunError),
    /// A measured surface map was refused (the file and why).
    #[error(transparent)]
    Map(#[from] metrology::MapError),
    /// A measured map could not be registered against its design.
    #[error("{}: {reason}", path.display())]
    Registration {
        /// The map file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// A measured FRF file was refused.
    #[error(transparent)]
    FrfFile(#[from] run_config::frf_file::FrfFileError),
    /// The linear model of the loop (a frequency response, a Lyapunov equation).
    #[error("loop model: {0}")]
    Model(#[from] lti::LtiError),
    /// A spectral estimate.
    #[error("spectral estimate: {0}")]
    Spectral(#[from] lti::spectral::SpectralError),
    /// The continuous plant model could not be built.
    #[error("plant model: {0}")]
    PlantModel(#[from] plant_sim::model::ModelError),
    /// The study needs the sampled linear plant, which the `coil` current-loop model lacks.
    #[error("{what} needs the ideal current-loop model (plant.actuator.model = \"ideal\")")]
    NeedsLinearPlant {
        /// The study.
        what: &'static str,
    },
    /// H2 synthesis found no controller.
    #[error("H2 synthesis: {0}")]
    Synthesis(#[from] design::h2::H2Error),
    /// Balanced truncation of a controller.
    #[error("controller reduction (needs a stable controller): {0}")]
    Reduction(lti::LtiError),
    /// PID tuning found no solution.
    #[error(transparent)]
    Tuning(#[from] design::tune::TuneError),
    /// No scaling of the configured PID satisfies the tuning bounds to start from.
    #[error(
        "no scaling of the configured PID is stable with |S| ≤ {ms}, |T| ≤ {mt}: raise ms or mt"
    )]
    NoTuningStart {
        /// Sensitivity bound.
        ms: f64,
        /// Complementary sensitivity bound.
        mt: f64,
    },
    /// No scaling of the configured PID reaches a bandwidth the study needs.
    #[error("no stable scaling of the configured PID reaches a {bandwidth_hz} Hz bandwidth")]
    BandwidthUnreachable {
        /// The bandwidth, Hz.
        bandwidth_hz: f64,
    },
    /// No H2 design of a study reaches its required bandwidth.
    #[error("no H2 design reaches a {bandwidth_hz} Hz bandwidth: {reason}")]
    BandwidthSearch {
        /// The required −3 dB bandwidth, Hz.
        bandwidth_hz: f64,
        /// How close it came, or why the search stopped.
        reason: String,
    },
    /// Grey-box identification failed.
    #[error("identification: {0}")]
    Identification(#[from] design::identify::IdentifyError),
    /// The grey-box fit does not explain the measured FRF (a closed-loop FRF, another plant,
    /// bad data): its parameters are not reported.
    #[error(
        "identification: fit {fit_percent:.1} % is below the {min:.0} % a credible fit reaches \
         (thesis §5.5.3: 97.7 %); is the FRF an open-loop one of this stage (--mass, config)?",
        min = crate::identify::MIN_CREDIBLE_FIT_PERCENT
    )]
    FitNotCredible {
        /// The fit reached, % (NaN when the fit broke down).
        fit_percent: f64,
    },
    /// A data file that cannot be used (a measured FRF, a study's journal or folder), at its
    /// line.
    #[error("{}:{line}: {what}", path.display())]
    DataFile {
        /// File.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// A measurement on a plant served on a prefix stopped to keep the stage safe: the plant
    /// was put back to 0 V and its run closed.
    #[error("FRF aborted at {freq_hz:.1} Hz: {what}; the plant was set to 0 V and its run closed — lower amplitude_v (or the band)")]
    FrfAborted {
        /// The frequency being measured, Hz.
        freq_hz: f64,
        /// What clipped.
        what: &'static str,
    },
    /// Writing results.
    #[error(transparent)]
    Report(#[from] crate::report::ReportError),
}
