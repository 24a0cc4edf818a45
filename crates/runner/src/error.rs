//! What can stop a run from being built or from running, each failure named.

use loop_model::feedforward::FeedforwardError;
use run_config::ConfigError;
use std::path::PathBuf;

/// Run errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// Configuration (file, key, allowed range).
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The simulator could not be built (a cutting profile it cannot apply; parameter errors
    /// are reported as [`RunError::Config`] at their key).
    #[error("plant: {0}")]
    Sim(plant_sim::sim::SimError),
    /// The controller and the plant form an unstable loop.
    #[error("the closed loop is unstable (spectral radius {}, must be < 1; NaN when coefficients overflow) with {controller}: lower the gains or check the controller file; nothing was run", readable(*radius))]
    Unstable {
        /// Largest closed-loop eigenvalue magnitude.
        radius: f64,
        /// Controller description.
        controller: String,
    },
    /// The loop closed on the measured FRF the run names (`controller.frf_file`) is unstable,
    /// or a loop within the measurement's uncertainty disks is.
    #[error("{}", unstable_on_measured(frf, *stable, *distance, *at_hz, controller))]
    UnstableOnMeasured {
        /// The FRF file and its SHA-256.
        frf: String,
        /// The measured loop itself is stable (only its uncertainty allows instability).
        stable: bool,
        /// The smallest `|1 + L| − r` (the uncertainty radius `r`), and where, Hz.
        distance: f64,
        /// Where the loop comes nearest −1, Hz.
        at_hz: f64,
        /// Controller description.
        controller: String,
    },
    /// The ZPETC or FIR feedforward could not be designed for this loop.
    #[error(transparent)]
    Feedforward(#[from] FeedforwardError),
    /// A measured FRF the run names was refused.
    #[error(transparent)]
    FrfFile(#[from] run_config::frf_file::FrfFileError),
    /// A design on measured data needs the plant's linear model (its sensor path), which the
    /// `coil` current-loop model has not.
    #[error("{what} needs a plant model with a linear tick (plant.actuator.model = \"ideal\" or \"first-order\")")]
    NeedsLinearPlant {
        /// What needed it.
        what: &'static str,
    },
    /// The loop's frequency response could not be evaluated (a pole on the unit circle).
    #[error(transparent)]
    Lti(#[from] lti::LtiError),
    /// Recording.
    #[error(transparent)]
    Record(#[from] recorder::RecordError),
    /// Reading a recording.
    #[error(transparent)]
    Read(#[from] recorder::ReadError),
    /// A shared-memory resource of the run could not be opened or used.
    #[error("transport: {0}")]
    Ipc(#[from] daq_io::ipc::IpcError),
    /// The host refused a real-time setting (`[realtime]` in the config).
    #[error("real-time settings ([realtime]): {0}")]
    Realtime(#[from] daq_io::realtime::RtError),
    /// The plant side of a HIL run failed.
    #[error("plant process: {0}")]
    Serve(#[from] daq_io::serve::ServeError),
    /// The controller's service (telemetry, health, control plane) could not start.
    #[error("controller service: {0}")]
    Service(#[from] servo_runtime::ServeError),
    /// Asked to stop (a signal, a library caller) before the run began: nothing was run or
    /// recorded.
    #[error("stopped ({}) before the run began: nothing was recorded", .0.signal_name().unwrap_or("a stop request"))]
    Stopped(crate::stop::EndReason),
    /// No plant or controller published on the run's services in time.
    #[error("no plant or controller joined run {prefix} within {waited_s} s")]
    NoPeers {
        /// Run prefix.
        prefix: String,
        /// Seconds waited.
        waited_s: f64,
    },
    /// The controller lost its plant.
    #[error("{0}; the controller stopped")]
    PlantLost(daq_io::DaqError),
    /// An input file embedded in a recording does not match the SHA-256 the recording states.
    #[error("{}: the embedded input {input} does not match its SHA-256 (the file was altered)", path.display())]
    InputMismatch {
        /// The recording.
        path: PathBuf,
        /// Attachment name.
        input: String,
    },
    /// A recording that is damaged or unfinished, read without being told to salvage it.
    #[error("{}: {report}; not trusted as a whole run (salvage reads what is intact)", path.display())]
    Damaged {
        /// The recording.
        path: PathBuf,
        /// What the read found, and where.
        report: String,
    },
    /// A recording without the metadata `servo run` writes.
    #[error("{0}: no fts-servo run metadata (was it written by `servo run`?)")]
    NotARun(PathBuf),
    /// A later part of a split recording: a replay starts at the run's first tick.
    #[error("{}: part {part} of a split recording; a replay starts at the run's first tick: replay its part 0 ({first})", .path.display())]
    LaterPart {
        /// The file.
        path: PathBuf,
        /// Its part index.
        part: u32,
        /// The recording's first part (its path; a name pattern when this file's name is not
        /// a part's).
        first: String,
    },
    /// The plant served on the prefix ended its run (its duration, a STOP, a fault) before
    /// this side was done with it.
    #[error("the plant ended its run at tick {ticks}{} before this measurement finished: start it with a longer run (run.duration_s)", if *faults != 0 { format!(" with faults {faults:#x}") } else { String::new() })]
    PlantEnded {
        /// The tick of its last sample.
        ticks: u64,
        /// Its fault flags ([`daq_io::flags::PLANT_FAULTS`] bits), 0 when it ended normally.
        faults: u32,
    },
    /// The plant on the prefix serves another rate than this side is configured for.
    #[error("the plant serves {served_hz:.1} Hz; this side is configured for {configured_hz:.1} Hz: set plant.timing.servo_rate_hz = {served_hz:.0} (or start the plant at the configured rate)")]
    RateMismatch {
        /// The plant's rate (from its sample times), Hz.
        served_hz: f64,
        /// The configured servo rate, Hz.
        configured_hz: f64,
    },
    /// A processor-in-the-loop run could not start or lost its target.
    #[error("processor in the loop: {0}")]
    Pil(#[from] crate::pil::PilError),
    /// A recording of a plant without simulator truth (a DAQ daemon, a real stage) asked to
    /// replay on the simulator's own stage.
    #[error("{}: recorded against a plant without simulator truth (a DAQ daemon or a real stage): its plant and noise cannot be re-run as they were; replay it on an identified plant model (a plant file, as `servo identify` writes it)", .0.display())]
    NoTruth(PathBuf),
    /// The stall the loop survives could not be predicted (the reason).
    #[error("the survivable stall is not predicted: {0}")]
    StallAnalysis(String),
    /// The processes of a HIL run could not be started or supervised (what failed).
    #[error("HIL processes: {0}")]
    Processes(String),
    /// A HIL process failed and the recorder gave no summary (the process said why on its
    /// standard error).
    #[error("servo {} exited with {}", .0.process, .0.code)]
    ChildFailed(ChildFailure),
    /// The host stalls longer than the loop survives: a real-time run would fail.
    #[error("{0}")]
    HostTooSlow(Box<crate::stall::verdict::Refusal>),
}

/// A spectral radius as a reader wants it: six decimals near 1, powers of ten when huge.
fn readable(radius: f64) -> String {
    if radius.abs() < 1e3 {
        format!("{radius:.6}")
    } else {
        format!("{radius:.3e}")
    }
}

/// Why the loop on a measured FRF was refused, in words.
fn unstable_on_measured(
    frf: &str,
    stable: bool,
    distance: f64,
    at_hz: f64,
    controller: &str,
) -> String {
    if stable {
        format!(
            "the measured FRF {frf} (controller.frf_file) allows an unstable loop with \
             {controller}: at {at_hz:.0} Hz its uncertainty disk reaches −1 (|1 + L| − r = \
             {distance:.3}); measure with more averages there or lower the gains; nothing was run"
        )
    } else {
        format!(
            "the closed loop on the measured FRF {frf} (controller.frf_file) is unstable with \
             {controller}: its Nyquist plot encircles −1 where the model's does not (nearest at \
             {at_hz:.0} Hz); lower the gains; nothing was run"
        )
    }
}

/// A child process that failed: it said why on its standard error.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChildFailure {
    /// Which process: `plant`, `controller` or `record`.
    pub process: String,
    /// Its exit code (-1: ended by a signal it did not handle).
    pub code: i32,
}

impl From<run_config::StageError> for RunError {
    fn from(e: run_config::StageError) -> Self {
        match e {
            run_config::StageError::Config(c) => RunError::Config(c),
            run_config::StageError::Sim(s) => RunError::Sim(s),
        }
    }
}
