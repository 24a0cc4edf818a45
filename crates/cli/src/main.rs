//! `servo`: run the fast tool servo closed loop against the simulated stage, record it, read
//! it back. A thin shell over the `runner` library: parsing, progress, printing.

use clap::{Args, Parser, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use plant_sim::params::{NoiseParams, StageParams};
use runner::analysis::Budget;
use runner::config::{ConfigError, ControllerKind, FeedforwardKind, Loaded, Scenario};
use runner::machine::{Machining, SurfaceConfig};
use runner::run::{closed_loop, run, RunError, RunOptions};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

mod hil;

#[derive(Parser)]
#[command(
    name = "servo",
    version,
    about = "Fast tool servo runtime and simulator (thesis prototype by default)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Where a run's recording and summary go.
#[derive(Args)]
struct Recording {
    /// Output MCAP file.
    #[arg(short, long, default_value = "run.mcap")]
    out: PathBuf,
    /// Do not write a file (summary only).
    #[arg(long)]
    no_record: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

impl Recording {
    /// The file to write, if any.
    fn out(&self) -> Option<PathBuf> {
        (!self.no_record).then(|| self.out.clone())
    }
}

/// Options of the HIL processes.
#[derive(Args, Clone)]
struct HilArgs {
    /// Run prefix of the iceoryx2 services (`fts-servo/<prefix>/…`): runs with different
    /// prefixes never interfere. `servo run --hil` picks `run-<pid>`.
    #[arg(long)]
    prefix: Option<String>,
    /// Pace ticks to the wall clock at the servo rate (late commands are overruns; the DAC
    /// holds its last value). Default: lockstep, as fast as possible, bit-identical to `servo run`.
    #[arg(long, conflicts_with = "lockstep")]
    realtime: bool,
    /// Lockstep pacing (the default).
    #[arg(long)]
    lockstep: bool,
    /// Controller silence after which the plant declares it lost and drives zero current, ms
    /// (default 200 lockstep, 0.5 real time; > 0).
    #[arg(long)]
    peer_timeout_ms: Option<f64>,
}

impl HilArgs {
    fn pacing(&self) -> daq_io::serve::Pacing {
        if self.realtime {
            daq_io::serve::Pacing::RealTime
        } else {
            daq_io::serve::Pacing::Lockstep
        }
    }

    fn peer_timeout(&self) -> Result<Option<std::time::Duration>, ExitCode> {
        match self.peer_timeout_ms {
            Some(t) if !(t > 0.0 && t < 1e7) => {
                eprintln!("error: --peer-timeout-ms = {t}: allowed 0 < t < 1e7 ms");
                Err(ExitCode::from(2))
            }
            t => Ok(t.map(|t| std::time::Duration::from_secs_f64(t * 1e-3))),
        }
    }

    /// The configuration and the run prefix a HIL process needs, or the exit code saying why
    /// not.
    fn resolve(&self, settings: &Settings) -> Result<(Loaded, String), ExitCode> {
        let cfg = settings.resolve().map_err(|e| fail(e, 2))?;
        Ok((cfg, self.prefix()?))
    }

    fn prefix(&self) -> Result<String, ExitCode> {
        self.prefix.clone().ok_or_else(|| {
            eprintln!(
                "error: --prefix is required (the run's service prefix, e.g. --prefix bench)"
            );
            ExitCode::from(2)
        })
    }
}

/// `servo ctl` messages.
#[derive(Subcommand, Clone, Copy)]
enum CtlAction {
    /// Start a plant waiting for it (`servo plant --wait-start`).
    Start,
    /// End the run at the next tick boundary (the recording is finished normally).
    Stop,
    /// Multiply the controller output (all gains) by SCALE (0.1..=10).
    Gain {
        /// Scale factor.
        scale: f64,
    },
}

impl CtlAction {
    /// The control-plane message.
    fn message(self) -> daq_io::Control {
        use daq_io::contract::command;
        let (command, value) = match self {
            CtlAction::Start => (command::START, 0.0),
            CtlAction::Stop => (command::STOP, 0.0),
            CtlAction::Gain { scale } => (command::SET_GAIN_SCALE, scale),
        };
        daq_io::Control {
            command,
            value,
            ..Default::default()
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Run the closed loop against the simulated stage and record it to MCAP.
    ///
    /// With no options: the thesis stage, the Chapter 7 PID at 199.6 kHz, sensor and current
    /// noise and base vibration on, holding position for 1 s, recorded to ./run.mcap.
    /// Example: servo run --mass heavy --scenario sine --amplitude 2e-6 --frequency 200
    Run {
        #[command(flatten)]
        settings: Settings,
        #[command(flatten)]
        recording: Recording,
        /// Run plant, controller and recorder as three processes over iceoryx2 shared memory
        /// (`servo plant`, `servo controller`, `servo record`); same summary.
        #[arg(long)]
        hil: bool,
        #[command(flatten)]
        hil_args: HilArgs,
    },
    /// Tune the PID (eq 7-8) for the largest integral gain under Ms, Mt and a bandwidth.
    ///
    /// On the simulator's exact sampled plant: the largest integral gain
    /// (best low-frequency disturbance rejection) with |S| ≤ Ms and |T| ≤ Mt everywhere and
    /// |T| ≥ −3 dB at the bandwidth, by convex-concave programming (clarabel LPs); compared with the
    /// configured (thesis Ch. 7) gains. Example: servo tune --bandwidth-hz 1000 --ms 1.5
    Tune {
        #[command(flatten)]
        settings: Settings,
        /// Closed-loop bandwidth to reach (|T| ≥ −3 dB there), Hz.
        #[arg(long, default_value_t = 1000.0)]
        bandwidth_hz: f64,
        /// Sensitivity peak bound Ms (1 < Ms < 10).
        #[arg(long, default_value_t = 1.5)]
        ms: f64,
        /// Complementary sensitivity peak bound Mt (1 < Mt < 10).
        #[arg(long, default_value_t = 1.3)]
        mt: f64,
        /// Run-config fragment with the tuned gains (`servo run -c FILE`).
        #[arg(short, long, default_value = "pid.toml")]
        out: PathBuf,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Identify the Table 5-2 stage parameters from an open-loop FRF (thesis §5.5.3).
    ///
    /// Fits m1 + m2, k2, c2, m4, k4, c4
    /// from an open-loop FRF CSV (as `servo frf --loop open` writes), with the simulator's exact
    /// sampled model as the grey box, starting from the configured stage.
    /// Example: servo frf --loop open --points 80 && servo identify frf/frf.csv
    Identify {
        /// FRF CSV with columns freq_hz, magnitude_m_per_v, phase_deg (clipped rows skipped).
        file: PathBuf,
        #[command(flatten)]
        settings: Settings,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Machine a freeform surface in simulation (thesis Ch. 8) and show the form error.
    ///
    /// Cuts the facing spiral over `--radius-range` with the spindle synchronised to the servo
    /// (encoder → angle → surface height per tick, §8.3), cutting force on, and writes the
    /// recording (MCAP), `machine.json` (form error PV/RMS, machined grid amplitude, following
    /// error), `form_map.csv`, `trajectory.csv` and pictures into `--out-dir`.
    /// Example: servo machine --surface sinusoidal-grid --feedforward zpetc
    Machine {
        #[command(flatten)]
        settings: Settings,
        #[command(flatten)]
        recording: Recording,
        /// Surface (default: the configured one, else the sinusoidal grid of Table 8-5).
        #[arg(long, value_enum)]
        surface: Option<SurfaceKind>,
        /// Greyscale PNG height map for --surface image.
        #[arg(long)]
        image: Option<PathBuf>,
        /// Pixel edge of the height map in m.
        #[arg(long, default_value_t = 20e-6)]
        pixel_m: f64,
        /// Height of a white pixel in m (Table 8-6: 5 µm).
        #[arg(long, default_value_t = 5e-6)]
        depth_range_m: f64,
        /// The band to cut, `inner:outer` radius in m (the tool moves inward from `outer`).
        #[arg(long, default_value = "24.95e-3:25e-3")]
        radius_range: String,
        /// Radial feed per revolution in m (5e-6, Tables 8-4..8-6).
        #[arg(long)]
        feed: Option<f64>,
        /// Cut from a flat blank in one pass (the depth of cut and the force follow the
        /// surface) instead of a finishing pass of constant depth over a pre-shaped part.
        #[arg(long)]
        flat_blank: bool,
        /// Directory for the analysis files.
        #[arg(long, default_value = "machine")]
        out_dir: PathBuf,
    },
    /// Separate spindle error motion from artefact form (thesis Appendix D) on simulated
    /// three-probe data: a known artefact and spindle motion measured with the three angle
    /// sets of Table D-1; reports how well each set, the thesis's frequency-domain
    /// modification and the least-squares synthesis recover both.
    /// Example: servo spindle-errors --probe-noise-m 0.3e-9
    SpindleErrors {
        /// Samples per revolution.
        #[arg(long, default_value_t = 10_000)]
        per_rev: usize,
        /// Revolutions averaged.
        #[arg(long, default_value_t = 32)]
        revolutions: usize,
        /// Highest harmonic analysed (UPR).
        #[arg(long, default_value_t = 100)]
        max_harmonic: usize,
        /// RMS of the simulated artefact form in m.
        #[arg(long, default_value_t = 20e-9)]
        artefact_rms_m: f64,
        /// RMS of the simulated synchronous spindle motion per axis in m.
        #[arg(long, default_value_t = 30e-9)]
        motion_rms_m: f64,
        /// RMS of the asynchronous motion in m.
        #[arg(long, default_value_t = 5e-9)]
        asynchronous_rms_m: f64,
        /// RMS of the probe noise in m.
        #[arg(long, default_value_t = 0.3e-9)]
        probe_noise_m: f64,
        /// Seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Directory for the results.
        #[arg(long, default_value = "spindle")]
        out_dir: PathBuf,
        /// Print the result as JSON.
        #[arg(long)]
        json: bool,
    },
    /// HIL: serve the simulated stage to a controller process.
    ///
    /// Lockstep or real time. A lost
    /// controller (no command for 200 ms lockstep / 0.5 ms real time) → zero current, exit 3.
    /// Example: servo plant --prefix bench --realtime
    Plant {
        #[command(flatten)]
        settings: Settings,
        #[command(flatten)]
        hil_args: HilArgs,
        /// Start without waiting for `servo record`.
        #[arg(long)]
        no_recorder: bool,
        /// After the peers are there, wait for `servo ctl start`.
        #[arg(long)]
        wait_start: bool,
    },
    /// HIL: run the controller against a plant process (simulator or DAQ daemon).
    ///
    /// Example: servo controller --prefix bench --mass heavy
    Controller {
        #[command(flatten)]
        settings: Settings,
        #[command(flatten)]
        hil_args: HilArgs,
    },
    /// HIL: record a run's telemetry and truth to MCAP and print its summary.
    ///
    /// Example: servo record --prefix bench --out bench.mcap
    Record {
        #[command(flatten)]
        settings: Settings,
        #[command(flatten)]
        hil_args: HilArgs,
        #[command(flatten)]
        recording: Recording,
    },
    /// HIL control plane: start a waiting plant, stop a run, or scale the controller's gains.
    ///
    /// Example: servo ctl --prefix bench gain 1.2
    Ctl {
        /// Run prefix.
        #[arg(long)]
        prefix: String,
        /// What to send.
        #[command(subcommand)]
        action: CtlAction,
    },
    /// Recompute and print the summary of a recording. Example: servo inspect run.mcap
    Inspect {
        /// The MCAP file written by `servo run`.
        file: PathBuf,
        /// Print the summary as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Error budget of the loop: per-source RMS and PSD, CAS, bandwidth sweep (thesis §5.7.2).
    ///
    /// Eq 5-13..5-17: each noise source's RMS and PSD
    /// in the following error (what the sensor reports) and the true tool error, their CAS; with
    /// --sweep the RMS errors against closed-loop bandwidth for both stage masses (Fig 5-14).
    /// Example: servo budget --mass heavy --sweep --validate 1
    Budget {
        #[command(flatten)]
        settings: Settings,
        /// Sweep the closed-loop bandwidth (the PID gains scaled) for the 0.075 and 0.175 kg stages.
        #[arg(long)]
        sweep: bool,
        /// Bandwidths of the sweep in Hz.
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "200,300,400,468,600,750,874,1000,1200,1450"
        )]
        bandwidths: Vec<f64>,
        /// Also simulate every sweep point for this many seconds and print both.
        #[arg(long)]
        validate: Option<f64>,
        /// Output directory for CSV, JSON, PNG and SVG.
        #[arg(long, default_value = "budget")]
        out_dir: PathBuf,
        /// Frequency points of the spectra (log-spaced, 1 Hz to Nyquist).
        #[arg(long, default_value_t = 2000)]
        points: usize,
    },
    /// Measure a frequency response on the running simulator and compare it with the model.
    ///
    /// Stepped sine (§5.5.1: ramp,
    /// settle, integer periods, exact-bin DFT) and compare it with the model: open loop (DAC
    /// command → measured position) or closed loop (injection at the controller output, §5.7.5).
    /// Example: servo frf --loop closed --from 10 --to 20000 --points 40
    Frf {
        #[command(flatten)]
        settings: Settings,
        /// Which loop.
        #[arg(long = "loop", value_enum, default_value = "open")]
        which: LoopKind,
        /// Lowest frequency in Hz.
        #[arg(long, default_value_t = 10.0)]
        from: f64,
        /// Highest frequency in Hz.
        #[arg(long, default_value_t = 20000.0)]
        to: f64,
        /// Frequencies (log-spaced).
        #[arg(long, default_value_t = 30)]
        points: usize,
        /// Excitation amplitude in V (stepped sine: below 150 Hz, rising as f² above, up to 5 V;
        /// chirp: constant, default 0.2 V closed loop / 0.002 V open loop).
        #[arg(long)]
        amplitude: Option<f64>,
        /// Stepped sine (§5.5.1) or a repeated exponential chirp with a Welch H1 estimate.
        #[arg(long, value_enum, default_value = "stepped")]
        method: FrfMethod,
        /// Output directory for CSV, JSON, PNG and SVG.
        #[arg(long, default_value = "frf")]
        out_dir: PathBuf,
    },
    /// Dynamic compliance X/dF at the tool with acceleration feedback (eq 7-9).
    ///
    /// Thesis eq 7-9, Table
    /// 7-1): analytic and from the simulator's sampled loop, for a list of Ka, PID gains fixed or
    /// scaled by 1/Kg (§7.4.1). Example: servo stiffness --kas 0,0.5,1,4 --kg-scaling --mass heavy
    Stiffness {
        #[command(flatten)]
        settings: Settings,
        /// Acceleration gains (V/V).
        #[arg(long, value_delimiter = ',', default_value = "0,0.5,1,4")]
        kas: Vec<f64>,
        /// Frequencies from 10 Hz to this (Hz), log-spaced.
        #[arg(long, default_value_t = 10000.0)]
        to: f64,
        /// Output directory for CSV, JSON, PNG and SVG.
        #[arg(long, default_value = "stiffness")]
        out_dir: PathBuf,
    },
    /// The intermittent cut of §7.6 for a list of acceleration gains: peak following error
    /// and the form-error height at the step edge per Ka (thesis: 75 → 25 nm and 106 → 27 nm
    /// for Ka 0 → 4). The acceleration loop needs a shaping filter Ha that keeps its phase:
    /// Example: servo intermittent-cut --mass heavy --kg-scaling --accel-filter-hz 300 --accel-filter-order 1
    IntermittentCut {
        #[command(flatten)]
        settings: Settings,
        /// Acceleration gains (V/V).
        #[arg(long, value_delimiter = ',', default_value = "0,0.5,1,4")]
        kas: Vec<f64>,
        /// Output directory for CSV and JSON.
        #[arg(long, default_value = "intermittent")]
        out_dir: PathBuf,
        /// Print the table as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Design an H2-optimal controller and write a controller file (thesis Ch. 6).
    ///
    /// `h2`: the H2-optimal controller on the simulator's exact discrete
    /// model at the configured servo rate (thesis Ch. 6): minimises the true tool error given the
    /// sensor, current, base and converter noise, knowing the loop delay; writes a controller
    /// file for `servo run --controller ss --ss-file FILE`.
    /// Example: servo synth h2 --rate 20000 --mass heavy --out h2.toml
    Synth {
        /// Method (only `h2` so far).
        #[arg(value_enum)]
        method: SynthMethod,
        #[command(flatten)]
        settings: Settings,
        /// Weight of 1 V of command against 1 nm of tool error (ρ, nm/V): larger = gentler.
        /// Default 1 (exact); with `--weights thesis` it weighs a volt above the Wu corner,
        /// default 1000 (loop-gain crossover ≈ 1 kHz on the heavy stage; thesis: 870 Hz).
        #[arg(long)]
        effort_weight: Option<f64>,
        /// Reduce the controller to this many states by balanced truncation (thesis Table 6-1:
        /// 8, 13; default: full order).
        #[arg(long)]
        order: Option<usize>,
        /// Design problem: `exact` — the simulator's exact discrete model and noise, true tool
        /// error (nm) and ρ·u penalised; `thesis` — §6.3 / Fig 6-3: the continuous model with
        /// We (eq 6-3, Ms of eq 6-4 at ξ = 0.707), ρ·Wu (eq 6-5), Ws, Wi, Wg, Wfc, discretised
        /// with the loop delay.
        #[arg(long, value_enum, default_value = "exact")]
        weights: Weights,
        /// Controller file to write.
        #[arg(short, long, default_value = "h2.toml")]
        out: PathBuf,
    },
    /// Show the fully resolved configuration (every number) after the file and the flags.
    /// Example: servo config --dump --mass heavy
    Config {
        #[command(flatten)]
        settings: Settings,
        /// Print the whole resolved configuration (the default action).
        #[arg(long)]
        dump: bool,
        /// As JSON instead of TOML.
        #[arg(long)]
        json: bool,
    },
}

#[derive(Clone, Copy, ValueEnum)]
enum Mass {
    /// 0.074 kg moving mass (Table 5-2).
    Light,
    /// 0.175 kg: +0.100 kg on the coil carrier (§5.7.3).
    Heavy,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum ScenarioKind {
    /// Hold position (§5.7.3).
    Hold,
    /// Sine reference (--amplitude, --frequency).
    Sine,
    /// Step reference (--amplitude) at 20 % of the run.
    Step,
    /// Exponential chirp over the run (--amplitude, --frequency to --f-end).
    Chirp,
    /// Hold during the §7.6 intermittent cut (--force, --rpm).
    IntermittentCut,
    /// Cut the default freeform surface (see `servo machine`; --rpm).
    Machine,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum SurfaceKind {
    /// Sinusoidal grid, ±5 µm, 1 mm wavelengths (Table 8-5; 60 rpm).
    SinusoidalGrid,
    /// Beam integrator: R 100 mm lenslets on a 2 mm pitch (Table 8-4; 120 rpm).
    BeamIntegrator,
    /// Single-path micro-lenslets, 10 µm, 375 per revolution (Table 8-3; 16 rpm).
    MicroLenslet,
    /// Greyscale PNG height map (--image; Table 8-6; 30 rpm).
    Image,
}

#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Ff {
    /// Feedback only.
    None,
    /// Stage-model velocity/acceleration/stiffness feedforward.
    Model,
    /// Zero-phase-error tracking (ZPETC) with preview, to the true tool position.
    Zpetc,
    /// ZPETC to the sensor reading (zero following error; the tool leads by the sensor lag).
    ZpetcSensor,
}

#[derive(Clone, Copy, ValueEnum)]
enum FrfMethod {
    /// One frequency at a time, exact-bin DFT, block coherence.
    Stepped,
    /// 16 periods of a 0.2 s exponential chirp, H1 and coherence per bin.
    Chirp,
}

#[derive(Clone, Copy, ValueEnum)]
enum SynthMethod {
    /// H2-optimal output feedback (discrete, exact model).
    H2,
}

#[derive(Clone, Copy, ValueEnum)]
enum LoopKind {
    /// No controller: DAC command → measured position.
    Open,
    /// Controller running, injection added to its output.
    Closed,
}

#[derive(Clone, Copy, ValueEnum)]
enum Ctrl {
    /// Position PID (eq 7-8).
    Pid,
    /// PID with acceleration feedback (Fig 7-6), gain --ka.
    Accel,
    /// State-space controller from --ss-file.
    Ss,
}

/// Settings shared by `run` and `config`: a TOML file, then flags on top.
#[derive(Args)]
struct Settings {
    /// TOML configuration file (see `servo config --dump` for every key).
    #[arg(short, long)]
    config: Option<PathBuf>,
    /// Simulated duration in s.
    #[arg(long)]
    duration: Option<f64>,
    /// Servo (loop) rate in Hz.
    #[arg(long)]
    rate: Option<f64>,
    /// Noise seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Controller.
    #[arg(long, value_enum)]
    controller: Option<Ctrl>,
    /// Acceleration feedback gain Ka (V/V), for --controller accel.
    #[arg(long)]
    ka: Option<f64>,
    /// Scale the PID gains by 1/Kg with acceleration feedback (§7.4.1).
    #[arg(long)]
    kg_scaling: bool,
    /// Controller file for --controller ss.
    #[arg(long)]
    ss_file: Option<PathBuf>,
    /// Stage preset (replaces [plant.stage]).
    #[arg(long, value_enum)]
    mass: Option<Mass>,
    /// Scenario.
    #[arg(long, value_enum)]
    scenario: Option<ScenarioKind>,
    /// Reference amplitude in m (sine, step, chirp).
    #[arg(long)]
    amplitude: Option<f64>,
    /// Sine frequency, or chirp start frequency, in Hz.
    #[arg(long)]
    frequency: Option<f64>,
    /// Chirp end frequency in Hz.
    #[arg(long)]
    f_end: Option<f64>,
    /// Cutting force in N (intermittent-cut).
    #[arg(long)]
    force: Option<f64>,
    /// Spindle speed in rpm (intermittent-cut, machine).
    #[arg(long)]
    rpm: Option<f64>,
    /// Corner of the acceleration shaping filter Ha in Hz (0: none).
    #[arg(long)]
    accel_filter_hz: Option<f64>,
    /// Order of Ha: 1 or 2.
    #[arg(long)]
    accel_filter_order: Option<u8>,
    /// Feedforward from the reference.
    #[arg(long, value_enum)]
    feedforward: Option<Ff>,
    /// Zero-phase smoothing of the previewed reference in Hz (Hann window; 0 = off), for
    /// surfaces with kinks or steps.
    #[arg(long)]
    smoothing_hz: Option<f64>,
    /// Noise sources on: comma list of sensor,current,base,accel, or `none` / `all`.
    #[arg(long)]
    noise: Option<String>,
}

impl Settings {
    /// The configuration: defaults, then the file, then the flags.
    fn resolve(&self) -> Result<Loaded, ConfigError> {
        let mut l = match &self.config {
            Some(p) => Loaded::from_file(p)?,
            None => Loaded::default(),
        };
        let c = &mut l.config;
        set(&mut c.run.duration_s, self.duration);
        set(&mut c.plant.timing.servo_rate_hz, self.rate);
        set(&mut c.run.seed, self.seed);
        if let Some(k) = self.controller {
            c.controller.kind = match k {
                Ctrl::Pid => ControllerKind::Pid,
                Ctrl::Accel => ControllerKind::Accel,
                Ctrl::Ss => ControllerKind::Ss,
            };
        }
        set(&mut c.controller.ka, self.ka);
        c.controller.kg_scaling |= self.kg_scaling;
        if let Some(p) = &self.ss_file {
            c.controller.ss_file = Some(
                std::env::current_dir()
                    .map(|d| d.join(p))
                    .unwrap_or(p.clone()),
            );
        }
        if let Some(m) = self.mass {
            c.plant.stage = match m {
                Mass::Light => StageParams::THESIS,
                Mass::Heavy => StageParams::THESIS_HEAVY,
            };
        }
        if let Some(kind) = self.scenario {
            let a = self.amplitude.unwrap_or(1e-6);
            let f = self.frequency.unwrap_or(100.0);
            c.scenario = match kind {
                ScenarioKind::Hold => Scenario::Hold,
                ScenarioKind::Sine => Scenario::Sine {
                    amplitude_m: a,
                    frequency_hz: f,
                },
                ScenarioKind::Step => Scenario::Step {
                    amplitude_m: a,
                    at_s: 0.2 * c.run.duration_s,
                },
                ScenarioKind::Chirp => Scenario::Chirp {
                    amplitude_m: a,
                    f_start_hz: self.frequency.unwrap_or(10.0),
                    f_end_hz: self.f_end.unwrap_or(2000.0),
                },
                ScenarioKind::IntermittentCut => Scenario::IntermittentCut {
                    force_n: self.force.unwrap_or(1.0),
                    spindle_rpm: self.rpm.unwrap_or(250.0),
                },
                ScenarioKind::Machine => Scenario::Machine(Machining::default()),
            };
        }
        if let Scenario::Machine(m) = &mut c.scenario {
            set(&mut m.spindle_rpm, self.rpm);
        }
        set(&mut c.controller.accel_filter_hz, self.accel_filter_hz);
        set(
            &mut c.controller.accel_filter_order,
            self.accel_filter_order,
        );
        set(&mut c.controller.smoothing_hz, self.smoothing_hz);
        if let Some(f) = self.feedforward {
            c.controller.feedforward = match f {
                Ff::None => FeedforwardKind::None,
                Ff::Model => FeedforwardKind::Model,
                Ff::Zpetc => FeedforwardKind::Zpetc,
                Ff::ZpetcSensor => FeedforwardKind::ZpetcSensor,
            };
        }
        if let Some(list) = &self.noise {
            match noise_from(list, c.plant.noise) {
                Ok(n) => c.plant.noise = n,
                Err(bad) => {
                    return Err(l.invalid("--noise", bad, "sensor,current,base,accel | all | none"))
                }
            }
        }
        Ok(l)
    }
}

/// Overrides `field` with a command-line `flag` when one was given.
fn set<T>(field: &mut T, flag: Option<T>) {
    if let Some(v) = flag {
        *field = v;
    }
}

fn noise_from(list: &str, mut n: NoiseParams) -> Result<NoiseParams, String> {
    let all = |n: &mut NoiseParams, on| (n.sensor, n.current, n.base, n.accel) = (on, on, on, on);
    all(&mut n, false);
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match item {
            "none" => all(&mut n, false),
            "all" => all(&mut n, true),
            "sensor" => n.sensor = true,
            "current" => n.current = true,
            "base" => n.base = true,
            "accel" => n.accel = true,
            other => return Err(other.to_string()),
        }
    }
    Ok(n)
}

/// Prints the error with its chain of causes (`error: writing x: I/O error: No space left…`).
/// A progress bar labelled `what` (hidden with `quiet`).
fn progress_bar(quiet: bool, what: &str) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {what} [{{bar:40}}] {{percent:>3}}% {{elapsed_precise}} ETA {{eta}}"
        ))
        .expect("valid template")
        .progress_chars("=> "),
    );
    bar
}

/// Runs `f` with the recording, Ctrl-C stop flag and progress bar (labelled `what`) of `rec`.
fn with_progress<T>(
    rec: &Recording,
    what: &str,
    f: impl FnOnce(RunOptions<'_>) -> Result<T, RunError>,
) -> Result<T, RunError> {
    let stop = stop_flag();
    let bar = progress_bar(rec.quiet, what);
    let mut progress = |done: u64, total: u64| {
        bar.set_length(total);
        bar.set_position(done);
    };
    let result = f(RunOptions {
        out: rec.out(),
        stop: &stop,
        progress: &mut progress,
    });
    bar.finish_and_clear();
    result
}

/// The exit code of a command: 0, 2 for configuration problems (bad input, a controller that
/// would make the loop unstable), 1 for run-time ones.
fn done(result: Result<(), RunError>) -> ExitCode {
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e @ (RunError::Config(_) | RunError::Unstable { .. })) => fail(e, 2),
        Err(e) => fail(e, 1),
    }
}

/// A stop flag raised by Ctrl-C / SIGTERM (a second one is ignored: the file is being
/// finished).
fn stop_flag() -> Arc<AtomicBool> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    let _ = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed));
    stop
}

fn fail(e: impl std::error::Error, code: u8) -> ExitCode {
    let mut msg = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !msg.contains(&text) {
            msg = format!("{msg}: {text}");
        }
        cause = c.source();
    }
    eprintln!("error: {msg}");
    ExitCode::from(code)
}

/// Prints any result as pretty JSON (everything printed serialises).
fn print_json(value: &impl serde::Serialize) {
    println!(
        "{}",
        serde_json::to_string_pretty(value).expect("results serialise")
    );
}

fn print_summary(s: &runner::summary::Summary, json: bool) {
    if json {
        print_json(s);
    } else {
        print!("{s}");
    }
}

fn print_margins(cfg: &runner::config::Loaded) {
    match runner::run::loop_margins(cfg) {
        Ok(m) => {
            let f = |v: Option<f64>, unit: &str| {
                v.map_or("–".to_string(), |x| format!("{x:.1} {unit}"))
            };
            println!(
                "  margins (loop broken at the DAC): phase {} at {}, gain {} at {}, lower gain {}",
                f(m.phase_margin_deg, "°"),
                f(m.gain_crossover_hz, "Hz"),
                f(m.gain_margin_db, "dB"),
                f(m.phase_crossover_hz, "Hz"),
                f(m.lower_gain_margin_db, "dB")
            );
        }
        Err(e) => println!("  margins: {e}"),
    }
}

fn print_written(w: &runner::report::Written) {
    let names: Vec<String> = w.files.iter().map(|p| p.display().to_string()).collect();
    println!("  wrote {}", names.join(", "));
    if let Some(n) = &w.note {
        println!("  note: {n}");
    }
}

/// `inner:outer` in m.
fn radius_range(text: &str) -> Option<(f64, f64)> {
    let (a, b) = text.split_once(':')?;
    let (inner, outer) = (a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?);
    (inner >= 0.0 && outer > inner && outer <= 1.0).then_some((inner, outer))
}

fn machine(
    s: &Settings,
    rec: &Recording,
    surface: Option<(SurfaceConfig, f64)>,
    range: &str,
    feed: Option<f64>,
    flat_blank: bool,
    out_dir: &Path,
) -> Result<(), RunError> {
    let mut cfg = s.resolve()?;
    let Some((inner, outer)) = radius_range(range) else {
        return Err(cfg
            .invalid(
                "--radius-range",
                range,
                "inner:outer in m, 0 ≤ inner < outer ≤ 1",
            )
            .into());
    };
    let mut m = match &cfg.config.scenario {
        Scenario::Machine(m) => m.clone(),
        _ => Machining::default(),
    };
    if let Some((surface, rpm)) = surface {
        m.surface = surface;
        m.spindle_rpm = s.rpm.unwrap_or(rpm);
    }
    if let Some(f) = feed {
        m.feed_m_per_rev = f;
    }
    if flat_blank {
        m.finish_depth_m = None;
    }
    m.start_radius_m = outer;
    let duration = m.duration_to(inner);
    cfg.config.scenario = Scenario::Machine(m);
    if s.duration.is_none() {
        cfg.config.run.duration_s = duration;
    }
    let (summary, analysis) = with_progress(rec, "machining", |opts| {
        runner::form::run_machining(&cfg, opts)
    })?;
    let title = format!(
        "{}, {}",
        summary.meta.controller,
        match cfg.config.controller.feedforward {
            FeedforwardKind::None => "no feedforward",
            FeedforwardKind::Model => "model feedforward",
            FeedforwardKind::Zpetc => "ZPETC feedforward (tool)",
            FeedforwardKind::ZpetcSensor => "ZPETC feedforward (sensor)",
        }
    );
    let written = runner::report::machining(&analysis, &title, out_dir)?;
    let report = analysis.report();
    if rec.json {
        print_json(&report);
        return Ok(());
    }
    print_summary(&summary, false);
    print_form(&report);
    if summary.saturated_ticks > 0 && cfg.config.controller.smoothing_hz == 0.0 {
        println!(
            "  note: the DAC saturated for {} ticks: the surface has kinks or steps the loop cannot follow; try --smoothing-hz 5000",
            summary.saturated_ticks
        );
    }
    if let Some(o) = rec.out() {
        println!("  wrote {}", o.display());
    }
    print_written(&written);
    Ok(())
}

/// `servo inspect`: the summary of a recording, and the form report of a machining run.
fn inspect_file(file: &Path, json: bool) -> Result<(), RunError> {
    let (loaded, rec) = runner::run::read_run(file)?;
    let summary = runner::run::summarise(&loaded, &rec);
    let form = runner::form::from_recording(&loaded, &rec)?.map(|a| a.report());
    if json {
        match form {
            Some(f) => print_json(&serde_json::json!({ "summary": summary, "form": f })),
            None => print_json(&summary),
        }
        return Ok(());
    }
    print_summary(&summary, false);
    if let Some(f) = &form {
        print_form(f);
    }
    Ok(())
}

/// The form report of a machining run, in a few lines.
fn print_form(report: &runner::form::FormReport) {
    let nm = |v: f64| v * 1e9;
    println!(
        "  machined band {:.3}–{:.3} mm ({:.1} revolutions)",
        report.band_m[0] * 1e3,
        report.band_m[1] * 1e3,
        report.revolutions
    );
    println!(
        "  form error (tool − design): RMS {:.1} nm, PV {:.1} nm, max |e| {:.1} nm",
        nm(report.form_error_m.rms),
        nm(report.form_error_m.pv),
        nm(report.max_abs_form_error_m)
    );
    if let Some(g) = report.grid {
        println!(
            "  grid peak-to-valley: X {:.3} µm, Y {:.3} µm (nominal {:.3} µm; thesis edge 11.18 µm without feedforward)",
            g.machined_pv_x_m * 1e6,
            g.machined_pv_y_m * 1e6,
            g.nominal_pv_x_m * 1e6
        );
    }
    if let Some(f) = report.max_motion_frequency_hz {
        println!("  fastest tool motion {f:.0} Hz at the outer radius");
    }
}

fn spindle_errors(
    s: &runner::spindle::SpindleStudy,
    out_dir: &Path,
    json: bool,
) -> Result<(), RunError> {
    let bad = |key: &str, v: String, range: &str| -> RunError {
        Loaded::default().invalid(key, v, range).into()
    };
    if !(64..=1 << 20).contains(&s.per_rev) {
        return Err(bad("--per-rev", s.per_rev.to_string(), "64..=1048576"));
    }
    if !(1..=10_000).contains(&s.revolutions) {
        return Err(bad("--revolutions", s.revolutions.to_string(), "1..=10000"));
    }
    if !(2..s.per_rev / 2).contains(&s.max_harmonic) {
        return Err(bad(
            "--max-harmonic",
            s.max_harmonic.to_string(),
            "2..per_rev/2",
        ));
    }
    for (key, v) in [
        ("--artefact-rms-m", s.artefact_rms_m),
        ("--motion-rms-m", s.motion_rms_m),
        ("--asynchronous-rms-m", s.asynchronous_rms_m),
        ("--probe-noise-m", s.probe_noise_rms_m),
    ] {
        if !(0.0..=1e-3).contains(&v) {
            return Err(bad(key, v.to_string(), "[0, 1e-3] m"));
        }
    }
    let (report, profiles) = runner::spindle::study(s);
    let written = runner::report::spindle(&report, &profiles, s.max_harmonic, out_dir)?;
    if json {
        print_json(&report);
        return Ok(());
    }
    let nm = |v: f64| v * 1e9;
    println!(
        "Three-probe separation (Appendix D): artefact {:.2} nm RMS, X {:.2} nm, Y {:.2} nm; {} revolutions × {} samples, probe noise {:.2} nm",
        nm(report.truth_rms_m[0]),
        nm(report.truth_rms_m[1]),
        nm(report.truth_rms_m[2]),
        s.revolutions,
        s.per_rev,
        nm(s.probe_noise_rms_m)
    );
    println!("  RMS error of the recovered          artefact        X        Y   (nm)");
    for (i, set) in report.sets.iter().enumerate() {
        let row = |name: String, r: &runner::spindle::Recovery| {
            println!(
                "  {name:<34} {:>8.3} {:>8.3} {:>8.3}",
                nm(r.artefact_rms_error_m),
                nm(r.x_rms_error_m),
                nm(r.y_rms_error_m)
            )
        };
        row(
            format!(
                "set #{} (min |H| {:.3} at {} UPR)",
                i + 1,
                set.min_weighting,
                set.min_weighting_upr
            ),
            &set.alone,
        );
        row(format!("set #{} modified", i + 1), &set.modified);
    }
    let r = &report.synthesised;
    println!(
        "  {:<34} {:>8.3} {:>8.3} {:>8.3}",
        "least-squares synthesis",
        nm(r.artefact_rms_error_m),
        nm(r.x_rms_error_m),
        nm(r.y_rms_error_m)
    );
    println!(
        "  predicted noise floor of the synthesis {:.3} nm; spread between the sets {:.3} → {:.3} nm after modification",
        nm(report.predicted_noise_m),
        nm(report.spread_m[0]),
        nm(report.spread_m[1])
    );
    print_written(&written);
    Ok(())
}

fn budget(
    s: &Settings,
    sweep: bool,
    bandwidths: &[f64],
    validate: Option<f64>,
    dir: &Path,
    points: usize,
) -> Result<(), RunError> {
    let cfg = s.resolve()?;
    let (cl, controller) = closed_loop(&cfg)?;
    let b = Budget::new(&cl, points.max(16)).map_err(|e| RunError::Plant(e.to_string()))?;
    let mass = cfg.config.plant.stage.m1_kg + cfg.config.plant.stage.m2_kg;
    let title = format!("{controller}, {mass:.3} kg stage");
    println!("Error budget (thesis §5.7.2): {title}");
    println!(
        "  closed-loop bandwidth {:.1} Hz; RMS in nm, sources independent (powers add)",
        b.bandwidth_hz
    );
    print_margins(&cfg);
    println!("  {:<14} {:>10} {:>10}", "source", "following", "true");
    for c in &b.contributions {
        println!(
            "  {:<14} {:>10.4} {:>10.4}",
            c.source,
            c.following_rms_m * 1e9,
            c.true_rms_m * 1e9
        );
    }
    println!(
        "  {:<14} {:>10.4} {:>10.4}",
        "total",
        b.following_rms_m * 1e9,
        b.true_rms_m * 1e9
    );
    let w = runner::report::budget(&b, &title, dir)?;
    print_written(&w);
    if !sweep {
        return Ok(());
    }
    let bar = ProgressBar::new(bandwidths.len() as u64 * 2);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} sweeping [{bar:40}] {pos}/{len} points {elapsed_precise}",
        )
        .expect("valid")
        .progress_chars("=> "),
    );
    let mut results = Vec::new();
    for (i, (label, stage)) in [
        ("0.075 kg", StageParams::THESIS),
        ("0.175 kg", StageParams::THESIS_HEAVY),
    ]
    .into_iter()
    .enumerate()
    {
        let mut c = cfg.clone();
        c.config.plant.stage = stage;
        let offset = i as u64 * bandwidths.len() as u64;
        results.push(runner::sweep::sweep(
            &c,
            label,
            bandwidths,
            validate,
            &mut |done, _| bar.set_position(offset + done as u64),
        )?);
    }
    bar.finish_and_clear();
    println!(
        "Bandwidth sweep (thesis Fig 5-14), PID gains scaled; RMS in nm (predicted{})",
        if validate.is_some() {
            " / simulated"
        } else {
            ""
        }
    );
    for s in &results {
        for p in &s.points {
            let sim = |v: Option<f64>| v.map_or(String::new(), |x| format!(" / {:.3}", x * 1e9));
            println!(
                "  {} {:>7.1} Hz (×{:.3}): following {:.3}{}   true {:.3}{}",
                s.label,
                p.bandwidth_hz,
                p.gain_scale,
                p.predicted_following_m * 1e9,
                sim(p.simulated_following_m),
                p.predicted_true_m * 1e9,
                sim(p.simulated_true_m)
            );
        }
        println!("  {}: lowest following error at {:.0} Hz, lowest true error at {:.0} Hz (thesis: 874 Hz for 0.075 kg, 468 Hz for 0.175 kg)", s.label, s.optimum_following_hz, s.optimum_true_hz);
    }
    let w = runner::report::sweeps(&results, dir)?;
    print_written(&w);
    Ok(())
}

fn frf(
    s: &Settings,
    which: LoopKind,
    (from, to, n): (f64, f64, usize),
    amplitude: Option<f64>,
    method: FrfMethod,
    dir: &Path,
) -> Result<(), RunError> {
    use runner::frf::{chirp, stepped_sine, FrfLoop, FrfSettings};
    let cfg = s.resolve()?;
    let which = match which {
        LoopKind::Open => FrfLoop::Open,
        LoopKind::Closed => FrfLoop::Closed,
    };
    let mut settings = FrfSettings::for_loop(which);
    if let Some(a) = amplitude {
        settings.amplitude_v = a;
    }
    let n = n.max(2);
    let freqs = design::spectral::log_space(from, to, n);
    let bar = ProgressBar::new(n as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} stepped sine [{bar:40}] {pos}/{len} frequencies {elapsed_precise}",
        )
        .expect("valid")
        .progress_chars("=> "),
    );
    let pts = match method {
        FrfMethod::Stepped => stepped_sine(&cfg, which, &freqs, &settings, &mut |d, _| {
            bar.set_position(d as u64)
        })?,
        FrfMethod::Chirp => {
            let a = amplitude.unwrap_or(if which == FrfLoop::Open { 0.002 } else { 0.2 });
            chirp(&cfg, which, (from, to), a, 0.2, 16)?
        }
    };
    bar.finish_and_clear();
    let how = if matches!(method, FrfMethod::Chirp) {
        "chirp + H1"
    } else {
        "stepped sine"
    };
    println!("FRF ({which:?} loop, {how}), measured vs model of the sampled loop:");
    println!(
        "  {:>10} {:>12} {:>9} {:>9} {:>9} {:>9}",
        "Hz", "|H| (m/V)", "phase °", "Δ dB", "Δ °", "γ²"
    );
    let (mut worst_db, mut worst_deg) = (0.0f64, 0.0f64);
    let stride = (pts.len() / 30).max(1); // the table shows ~30 rows; the CSV has every point
    for (i, p) in pts.iter().enumerate() {
        if i % stride == 0 {
            println!(
                "  {:>10.2} {:>12.4e} {:>9.2} {:>+9.3} {:>+9.2} {:>9.5}{}",
                p.freq_hz,
                p.magnitude,
                p.phase_deg,
                p.error_db(),
                p.error_deg(),
                p.coherence,
                if p.clipped { "  CLIPPED" } else { "" }
            );
        }
        if p.coherence > 0.99 && !p.clipped {
            worst_db = worst_db.max(p.error_db().abs());
            worst_deg = worst_deg.max(p.error_deg().abs());
        }
    }
    println!("  where γ² > 0.99: largest deviation {worst_db:.3} dB, {worst_deg:.2}°");
    let curve = runner::frf::model_curve(&cfg, which, from, to, 600)?;
    let w = runner::report::frf(&pts, &curve, &format!("{which:?}-loop FRF"), dir)?;
    print_written(&w);
    Ok(())
}

fn intermittent(s: &Settings, kas: &[f64], dir: &Path, json: bool) -> Result<(), RunError> {
    let mut cfg = s.resolve()?;
    if !matches!(cfg.config.scenario, Scenario::IntermittentCut { .. }) {
        cfg.config.scenario = Scenario::IntermittentCut {
            force_n: s.force.unwrap_or(1.0),
            spindle_rpm: s.rpm.unwrap_or(250.0),
        };
    }
    if s.duration.is_none() {
        cfg.config.run.duration_s = 0.5;
    }
    let rows = runner::intermittent::study(&cfg, kas)?;
    let written = runner::report::intermittent(&rows, dir)?;
    if json {
        print_json(&rows);
        return Ok(());
    }
    println!("Intermittent cut (§7.6): force steps twice per revolution");
    println!(
        "  {:>5} {:>8} {:>22} {:>22} {:>16}",
        "Ka", "PID ×", "peak following (nm)", "edge form error (nm)", "following RMS"
    );
    for r in &rows {
        println!(
            "  {:>5} {:>8.3} {:>22.1} {:>22.1} {:>16.1}",
            r.ka,
            r.pid_scale,
            r.peak_following_error_m * 1e9,
            r.edge_form_error_m * 1e9,
            r.following_rms_m * 1e9
        );
    }
    print_written(&written);
    Ok(())
}

fn stiffness(s: &Settings, kas: &[f64], to: f64, dir: &Path) -> Result<(), RunError> {
    let cfg = s.resolve()?;
    let freqs = design::spectral::log_space(10.0, to, 200);
    let curves = runner::stiffness::compliance(&cfg, kas, s.kg_scaling, &freqs)?;
    println!(
        "Dynamic compliance at the tool (eq 7-9), {} PID gains:",
        if s.kg_scaling { "Kg-scaled" } else { "fixed" }
    );
    let at = |c: &runner::stiffness::ComplianceCurve, f: f64| {
        let i = c
            .freq_hz
            .iter()
            .position(|&x| x >= f)
            .unwrap_or(c.freq_hz.len() - 1);
        c.sampled_m_per_n[i] * 1e6
    };
    println!(
        "  {:>5} {:>8} {:>10} {:>10} {:>10} {:>10} {:>10}  (µm/N)",
        "Ka", "PID ×", "10 Hz", "100 Hz", "1 kHz", "5 kHz", "Δ dB"
    );
    for c in &curves {
        let worst = c
            .analytic_m_per_n
            .iter()
            .zip(&c.sampled_m_per_n)
            .map(|(a, b)| (20.0 * (a / b).log10()).abs())
            .fold(0.0, f64::max);
        println!(
            "  {:>5} {:>8.3} {:>10.4} {:>10.4} {:>10.4} {:>10.4} {:>10.3}{}",
            c.ka,
            c.pid_scale,
            at(c, 10.0),
            at(c, 100.0),
            at(c, 1000.0),
            at(c, 5000.0),
            worst,
            if c.stable() {
                String::new()
            } else {
                format!("  UNSTABLE (spectral radius {:.4})", c.spectral_radius)
            }
        );
    }
    let w = runner::report::stiffness(&curves, dir)?;
    print_written(&w);
    Ok(())
}

/// `servo synth h2 --weights`.
#[derive(Clone, Copy, ValueEnum)]
enum Weights {
    Exact,
    Thesis,
}

fn synth(
    s: &Settings,
    effort: Option<f64>,
    order: Option<usize>,
    weights: Weights,
    out: &Path,
) -> Result<(), RunError> {
    let cfg = s.resolve()?;
    let mut design = match weights {
        Weights::Exact => runner::synth::h2_design(&cfg, effort.unwrap_or(1.0))?,
        Weights::Thesis => runner::synth::thesis_design(
            &cfg,
            &runner::synth::ThesisWeights::default(),
            effort.unwrap_or(1000.0),
        )?,
    };
    if let Some(n) = order {
        let (reduced, hankel, bound) = design.reduced(n)?;
        let shown: Vec<String> = hankel.iter().take(16).map(|h| format!("{h:.2e}")).collect();
        println!(
            "Hankel singular values of the {}-state controller: {} …",
            design.controller.nx(),
            shown.join(" ")
        );
        println!("  kept {n} states; H∞ error bound of the controller {bound:.3e}");
        design = reduced;
    }
    std::fs::write(out, design.to_toml())
        .map_err(|e| RunError::Plant(format!("cannot write {}: {e}", out.display())))?;
    // Predict what it does with the budget of the loop it closes.
    let mut with = cfg.clone();
    with.config.controller.kind = ControllerKind::Ss;
    with.config.controller.ss_file = Some(std::fs::canonicalize(out).unwrap_or(out.to_owned()));
    let (cl, _) = closed_loop(&with)?;
    let b = Budget::new(&cl, 400).map_err(|e| RunError::Plant(e.to_string()))?;
    println!(
        "H2 controller: {} states at {:.0} Hz (thesis §6.4.1: 27)",
        design.controller.nx(),
        design.sample_rate_hz
    );
    println!(
        "  closed loop: spectral radius {:.6}, bandwidth {:.0} Hz",
        cl.spectral_radius(),
        b.bandwidth_hz
    );
    print_margins(&with);
    println!(
        "  predicted RMS: following {:.3} nm, true {:.3} nm",
        b.following_rms_m * 1e9,
        b.true_rms_m * 1e9
    );
    println!(
        "  wrote {} — run it: servo run --controller ss --ss-file {} --rate {}",
        out.display(),
        out.display(),
        design.sample_rate_hz
    );
    Ok(())
}

fn identify(s: &Settings, file: &Path, json: bool) -> Result<(), RunError> {
    let cfg = s.resolve()?;
    let (f, g) = runner::identify::read_frf_csv(file)?;
    let id = runner::identify::identify(&cfg, &f, &g)?;
    if json {
        print_json(&id);
        return Ok(());
    }
    println!(
        "Grey-box fit to {} ({} points, {} iterations): fit {:.2} % (thesis §5.5.3: 97.7 %), {:.2} % on relative errors",
        file.display(),
        id.points,
        id.iterations,
        id.fit_percent,
        id.weighted_fit_percent
    );
    println!(
        "  {:<12} {:>13} {:>9} {:>13}",
        "Table 5-2", "fitted", "1σ", "start"
    );
    for i in 0..id.names.len() {
        println!(
            "  {:<12} {:>13.5e} {:>8.2}% {:>13.5e}",
            id.names[i],
            id.fitted[i],
            100.0 * id.rel_std[i],
            id.start[i]
        );
    }
    Ok(())
}

fn tune(
    s: &Settings,
    bandwidth_hz: f64,
    (ms, mt): (f64, f64),
    out: &Path,
    json: bool,
) -> Result<(), RunError> {
    let cfg = s.resolve()?;
    let r = runner::tune::tune(&cfg, bandwidth_hz, ms, mt)?;
    std::fs::write(out, r.to_toml())
        .map_err(|e| RunError::Plant(format!("cannot write {}: {e}", out.display())))?;
    if json {
        print_json(&r);
        return Ok(());
    }
    println!(
        "PID tuned for max ki with |S| ≤ {ms}, |T| ≤ {mt}, |T| ≥ −3 dB at {bandwidth_hz:.0} Hz ({} LPs), on the exact sampled plant:",
        r.iterations
    );
    println!(
        "  {:<10} {:>8} {:>9} {:>10} {:>7} {:>7} {:>9} {:>9} {:>11} {:>9}",
        "",
        "kp",
        "ki 1/s",
        "kd s",
        "max|S|",
        "max|T|",
        "cross Hz",
        "T bw Hz",
        "follow nm",
        "true nm"
    );
    for (name, p) in [("configured", &r.reference), ("tuned", &r.tuned)] {
        println!(
            "  {:<10} {:>8.4} {:>9.1} {:>10.3e} {:>7.3} {:>7.3} {:>9.0} {:>9.0} {:>11.3} {:>9.3}",
            name,
            p.kp,
            p.ki,
            p.kd,
            p.max_sensitivity,
            p.max_complementary,
            p.crossover_hz,
            p.bandwidth_hz,
            p.following_rms_m * 1e9,
            p.true_rms_m * 1e9
        );
    }
    println!(
        "  integral gain {:.2}× the configured one; wrote {} — run it: servo run -c {}",
        r.tuned.ki / r.reference.ki,
        out.display(),
        out.display()
    );
    Ok(())
}

/// `servo run`, in process or (`hil`) as three processes: prints the summary; the exit code
/// is the first failing HIL child's.
fn run_command(cfg: &Loaded, rec: &Recording, hil: Option<&HilArgs>) -> Result<ExitCode, RunError> {
    let out = rec.out();
    let (summary, code) = match hil {
        Some(h) => {
            let (summary, codes) = hil::run(
                cfg,
                h.prefix.clone(),
                h.realtime,
                h.peer_timeout_ms,
                out.clone(),
                rec.quiet,
            )?;
            let code = match codes.iter().find(|(_, c)| *c != 0) {
                Some((name, c)) => {
                    eprintln!("servo {name} exited with {c}");
                    ExitCode::from(*c as u8)
                }
                None => ExitCode::SUCCESS,
            };
            (summary, code)
        }
        None => {
            let summary = with_progress(rec, "simulating", |opts| run(cfg, opts))?;
            (summary, ExitCode::SUCCESS)
        }
    };
    print_summary(&summary, rec.json);
    if let (Some(o), false) = (&out, rec.json) {
        println!(
            "  wrote {} (open it in Foxglove: topics /telemetry and /truth)",
            o.display()
        );
    }
    Ok(code)
}

fn main() -> ExitCode {
    // `servo … | head` must end quietly, not panic on a closed pipe.
    sigpipe::reset();
    let cli = Cli::parse();
    match cli.command {
        Command::Run {
            settings,
            recording,
            hil,
            hil_args,
        } => match settings.resolve() {
            Ok(cfg) => run_command(&cfg, &recording, hil.then_some(&hil_args))
                .unwrap_or_else(|e| done(Err(e))),
            Err(e) => fail(e, 2),
        },
        Command::Budget {
            settings,
            sweep,
            bandwidths,
            validate,
            out_dir,
            points,
        } => done(budget(
            &settings,
            sweep,
            &bandwidths,
            validate,
            &out_dir,
            points,
        )),
        Command::Frf {
            settings,
            which,
            from,
            to,
            points,
            amplitude,
            method,
            out_dir,
        } => done(frf(
            &settings,
            which,
            (from, to, points),
            amplitude,
            method,
            &out_dir,
        )),
        Command::IntermittentCut {
            settings,
            kas,
            out_dir,
            json,
        } => done(intermittent(&settings, &kas, &out_dir, json)),
        Command::Stiffness {
            settings,
            kas,
            to,
            out_dir,
        } => done(stiffness(&settings, &kas, to, &out_dir)),
        Command::Synth {
            method: SynthMethod::H2,
            settings,
            effort_weight,
            order,
            weights,
            out,
        } => done(synth(&settings, effort_weight, order, weights, &out)),
        Command::Tune {
            settings,
            bandwidth_hz,
            ms,
            mt,
            out,
            json,
        } => done(tune(&settings, bandwidth_hz, (ms, mt), &out, json)),
        Command::Machine {
            settings,
            recording,
            surface,
            image,
            pixel_m,
            depth_range_m,
            radius_range,
            feed,
            flat_blank,
            out_dir,
        } => {
            let surface = surface.map(|k| match k {
                SurfaceKind::SinusoidalGrid => (SurfaceConfig::THESIS_GRID, 60.0),
                SurfaceKind::BeamIntegrator => (SurfaceConfig::THESIS_BEAM, 120.0),
                SurfaceKind::MicroLenslet => (
                    SurfaceConfig::MicroLenslet {
                        amplitude_m: 10e-6,
                        per_revolution: 375.0,
                    },
                    16.0,
                ),
                SurfaceKind::Image => (
                    SurfaceConfig::Image {
                        path: image.clone().unwrap_or_default(),
                        pixel_m,
                        depth_range_m,
                    },
                    30.0,
                ),
            });
            done(machine(
                &settings,
                &recording,
                surface,
                &radius_range,
                feed,
                flat_blank,
                &out_dir,
            ))
        }
        Command::SpindleErrors {
            per_rev,
            revolutions,
            max_harmonic,
            artefact_rms_m,
            motion_rms_m,
            asynchronous_rms_m,
            probe_noise_m,
            seed,
            out_dir,
            json,
        } => done(spindle_errors(
            &runner::spindle::SpindleStudy {
                per_rev,
                revolutions,
                max_harmonic,
                artefact_rms_m,
                motion_rms_m,
                asynchronous_rms_m,
                probe_noise_rms_m: probe_noise_m,
                seed,
            },
            &out_dir,
            json,
        )),
        Command::Identify {
            file,
            settings,
            json,
        } => done(identify(&settings, &file, json)),
        Command::Plant {
            settings,
            hil_args,
            no_recorder,
            wait_start,
        } => match (hil_args.resolve(&settings), hil_args.peer_timeout()) {
            (Ok((cfg, p)), Ok(t)) => hil::plant(
                &cfg,
                &p,
                &runner::hil::PlantOptions {
                    pacing: hil_args.pacing(),
                    wait_for_recorder: !no_recorder,
                    wait_for_start: wait_start,
                    peer_timeout: t,
                },
            ),
            (Err(code), _) | (_, Err(code)) => code,
        },
        Command::Controller { settings, hil_args } => match hil_args.resolve(&settings) {
            Ok((cfg, p)) => hil::controller(&cfg, &p),
            Err(code) => code,
        },
        Command::Record {
            settings,
            hil_args,
            recording,
        } => match hil_args.resolve(&settings) {
            Ok((cfg, p)) => hil::record(&cfg, &p, &recording, hil_args.realtime),
            Err(code) => code,
        },
        Command::Ctl { prefix, action } => hil::ctl(&prefix, action.message()),
        Command::Inspect { file, json } => done(inspect_file(&file, json)),
        Command::Config {
            settings,
            dump: _,
            json,
        } => match settings.resolve() {
            Ok(l) => {
                if let Err(e) = l.config.validate(&l) {
                    return fail(e, 2);
                }
                if json {
                    print_json(&l.config);
                } else {
                    print!("{}", l.config.to_toml());
                }
                ExitCode::SUCCESS
            }
            Err(e) => fail(e, 2),
        },
    }
}
