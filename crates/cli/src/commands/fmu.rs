//! `servo fmu`: the stage or the controller as an FMI co-simulation unit (`.fmu`) for
//! Simulink, Modelica tools, FMPy or a HIL vendor's tool.

use crate::args::{PlantArgs, RunLengthArgs};
use crate::output::CliError;
use clap::{Args, Subcommand, ValueEnum};
use fmu::unit::{controller_files, stage_files};
use fmu::variables::MAX_SEED;
use fmu::{FmiVersion, UnitFiles};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Write the stage or the controller as an FMI co-simulation unit (.fmu).
///
/// The unit carries libfts_fmu for x86-64 Linux and steps whole servo ticks (a communication
/// step of n ticks; any other step is refused, never interpolated).
/// Example: servo fmu stage -c run.toml -o stage.fmu; servo fmu controller deploy.toml -o controller.fmu
#[derive(Args, Debug)]
pub struct FmuCmd {
    #[command(subcommand)]
    unit: Unit,
}

#[derive(Subcommand, Debug)]
enum Unit {
    /// The simulated stage as a unit: DAC command and force in, readings and tool position out
    ///
    /// The stage of a run configuration: the DAC command (V) and an external force (N) in, the
    /// gap and accelerometer readings (V), their flags and the true tool position (m) out;
    /// every plant value a parameter with its unit and range.
    Stage {
        #[command(flatten)]
        #[allow(missing_docs)]
        plant: PlantArgs,
        #[command(flatten)]
        #[allow(missing_docs)]
        length: RunLengthArgs,
        #[command(flatten)]
        #[allow(missing_docs)]
        out: OutArgs,
    },
    /// The controller of a deployment as a unit: readings in, DAC command and telemetry out
    ///
    /// The deployment's `Servo` (`servo deploy` writes deployments): the gap and accelerometer
    /// readings (V) in, the DAC command (V) and the tick's reference, measured position,
    /// following error (m), flags and trip out.
    Controller {
        /// Deployment file.
        deployment: PathBuf,
        /// The default experiment's length in s (positive).
        #[arg(long, value_parser = crate::args::positive, default_value_t = 0.1)]
        duration: f64,
        #[command(flatten)]
        #[allow(missing_docs)]
        out: OutArgs,
    },
}

/// Where the unit goes and in which FMI version.
#[derive(Args, Debug)]
struct OutArgs {
    /// The .fmu file to write.
    #[arg(short, long)]
    out: PathBuf,
    /// FMI version: 2 (what most tools load today) or 3.
    #[arg(long, value_enum, default_value_t = Version::V2)]
    fmi: Version,
    /// Replace the output file if it exists.
    #[arg(long)]
    overwrite: bool,
}

#[derive(ValueEnum, Clone, Copy, Debug)]
enum Version {
    #[value(name = "2")]
    V2,
    #[value(name = "3")]
    V3,
}

impl From<Version> for FmiVersion {
    fn from(v: Version) -> Self {
        match v {
            Version::V2 => FmiVersion::V2,
            Version::V3 => FmiVersion::V3,
        }
    }
}

/// libfts_fmu: `FTS_FMU_LIBRARY`, else beside the servo binary (a cargo build) or in the
/// `lib` folder next to its `bin` (an installation).
fn library() -> PathBuf {
    if let Some(p) = std::env::var_os("FTS_FMU_LIBRARY") {
        return p.into();
    }
    let exe = std::env::current_exe().unwrap_or_default();
    let dir = exe.parent().unwrap_or(Path::new("."));
    let beside = dir.join("libfts_fmu.so");
    if beside.exists() {
        return beside;
    }
    dir.join("../lib/libfts_fmu.so")
}

impl FmuCmd {
    /// Checks the configuration, writes the unit and says what it is.
    pub fn exec(&self) -> Result<ExitCode, CliError> {
        let (files, out) = match &self.unit {
            Unit::Stage { plant, length, out } => {
                let mut l = plant.load()?;
                length.apply(&mut l);
                let c = &l.config;
                c.validate(&l.origin)?;
                if let Some(seed) = c.run.practice_seed {
                    return Err(l
                        .origin
                        .invalid(
                            "run.practice_seed",
                            seed,
                            "unset: a stage unit is the configured stage",
                        )
                        .into());
                }
                if c.run.seed > MAX_SEED {
                    return Err(l
                        .origin
                        .invalid(
                            "run.seed",
                            c.run.seed,
                            &format!("[0, {MAX_SEED}] (an FMI 2 Integer)"),
                        )
                        .into());
                }
                // The plant builds (each value in range), or the error names its key.
                run_config::simulator(c, &l.origin).map_err(runner::RunError::from)?;
                let files = stage_files(out.fmi.into(), &c.plant, c.run.seed, c.run.duration_s);
                (files, out)
            }
            Unit::Controller {
                deployment,
                duration,
                out,
            } => {
                let servo = servo_runtime::Servo::from_file(deployment)?;
                let text =
                    std::fs::read_to_string(deployment).map_err(|source| CliError::Write {
                        path: deployment.clone(),
                        source,
                    })?;
                let files = controller_files(out.fmi.into(), &text, servo.period_s(), *duration);
                (files, out)
            }
        };
        write(&files, out)
    }
}

/// The largest library a unit carries, bytes.
const MAX_LIBRARY_BYTES: u64 = 256 << 20;

fn write(files: &UnitFiles, out: &OutArgs) -> Result<ExitCode, CliError> {
    let library = library();
    let binary =
        daq_io::input_file::read_regular(&library, MAX_LIBRARY_BYTES).map_err(|source| {
            CliError::FmuLibrary {
                path: library,
                source,
            }
        })?;
    // Placed as a recording is: written privately beside the target, moved into place whole,
    // an existing file kept unless --overwrite.
    let overwrite = recorder::Overwrite::from_flag(out.overwrite);
    recorder::check_target(&out.out, overwrite).map_err(runner::RunError::from)?;
    let partial = recorder::partial_path(&out.out);
    let io = |source| CliError::Write {
        path: out.out.clone(),
        source,
    };
    let written = recorder::create_private(&partial).and_then(|file| {
        let mut file = std::io::BufWriter::new(file);
        fmu::write_archive(&mut file, files, &binary)?;
        file.into_inner().map_err(|e| e.into_error())?.sync_all()
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&partial);
        return Err(io(e));
    }
    if let Err(e) = recorder::publish(&partial, &out.out, overwrite) {
        let _ = std::fs::remove_file(&partial);
        return Err(runner::RunError::from(e).into());
    }
    let bytes = std::fs::metadata(&out.out).map_err(io)?.len();
    let version = match files.version {
        FmiVersion::V2 => "2.0",
        FmiVersion::V3 => "3.0",
    };
    println!(
        "wrote {} ({:.1} MiB): FMI {version} co-simulation unit {}, binary for x86-64 Linux ({})",
        out.out.display(),
        bytes as f64 / (1u64 << 20) as f64,
        files.model_identifier,
        files.version.binary_dir()
    );
    Ok(ExitCode::SUCCESS)
}
