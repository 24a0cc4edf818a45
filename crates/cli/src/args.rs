//! Argument groups shared by several commands. Each command flattens only the groups it uses,
//! so a flag it would ignore is a clap error, not a silent no-op. Each group applies itself on
//! top of the configuration: defaults, then the `--config` file, then the flags.

use crate::choice::{choice, name_of};
use clap::Args;
use plant_sim::params::NoiseParams;
use run_config::presets::{ScenarioKind, ScenarioValues, StagePreset};
use run_config::{ConfigError, ControllerConfig, ControllerKind, FeedforwardKind, Loaded};
use std::num::{NonZeroU32, NonZeroU64};
use std::path::{Path, PathBuf};

/// The stage and where the configuration comes from (every command that models the loop).
#[derive(Args, Debug, Clone)]
pub struct PlantArgs {
    /// TOML configuration file (see `servo config --dump` for every key).
    #[arg(short, long)]
    pub config: Option<PathBuf>,
    /// Servo (loop) rate in Hz.
    #[arg(value_parser = crate::args::finite, long)]
    pub rate: Option<f64>,
    /// Plant file: a `[plant]` table only, e.g. the model.toml `servo identify` writes
    /// (replaces the configured plant; --rate and --noise still apply).
    #[arg(long, conflicts_with = "mass")]
    pub plant: Option<PathBuf>,
    /// Stage preset (replaces [plant.stage]).
    #[arg(long, value_parser = choice::<StagePreset>())]
    pub mass: Option<StagePreset>,
    /// Noise sources on: comma list of sensor,current,base,accel, or `none` / `all`.
    #[arg(long)]
    pub noise: Option<String>,
}

impl PlantArgs {
    /// These flags as a command line would give them (` -c cfg.toml --rate 20000 --mass
    /// heavy`): what a suggested follow-up command needs to run on the same plant.
    pub fn flags(&self) -> String {
        let mut out = String::new();
        if let Some(c) = &self.config {
            out += &format!(" -c {}", c.display());
        }
        if let Some(p) = &self.plant {
            out += &format!(" --plant {}", p.display());
        }
        if let Some(r) = self.rate {
            out += &format!(" --rate {r}");
        }
        if let Some(m) = self.mass {
            out += &format!(" --mass {}", name_of(&m));
        }
        if let Some(n) = &self.noise {
            out += &format!(" --noise {n}");
        }
        out
    }

    /// The configuration: defaults, then the file, then these flags.
    pub fn load(&self) -> Result<Loaded, ConfigError> {
        let mut l = match &self.config {
            Some(p) => Loaded::from_file(p)?,
            None => Loaded::default(),
        };
        let c = &mut l.config;
        if let Some(p) = &self.plant {
            c.plant = run_config::read_plant_file(p)?;
        }
        set(&mut c.plant.timing.servo_rate_hz, self.rate);
        if let Some(m) = self.mass {
            c.plant.stage = m.params();
        }
        if let Some(list) = &self.noise {
            c.plant.noise = noise_from(list, c.plant.noise).map_err(|bad| {
                l.origin
                    .invalid("--noise", bad, "sensor,current,base,accel | all | none")
            })?;
        }
        Ok(l)
    }
}

/// The simulated run's length and noise seed.
#[derive(Args, Debug, Clone)]
pub struct RunLengthArgs {
    /// Simulated duration in s.
    #[arg(value_parser = crate::args::finite, long)]
    pub duration: Option<f64>,
    /// Noise seed.
    #[arg(long)]
    pub seed: Option<u64>,
}

impl RunLengthArgs {
    /// Applies the flags.
    pub fn apply(&self, l: &mut Loaded) {
        set(&mut l.config.run.duration_s, self.duration);
        set(&mut l.config.run.seed, self.seed);
    }
}

/// The acceleration loop's settings (§7.4).
#[derive(Args, Debug, Clone)]
pub struct AccelArgs {
    /// Scale the PID gains by 1/Kg with acceleration feedback (§7.4.1).
    #[arg(long)]
    pub kg_scaling: bool,
    /// Corner of the acceleration shaping filter Ha in Hz (0: none).
    #[arg(value_parser = crate::args::finite, long)]
    pub accel_filter_hz: Option<f64>,
    /// Order of Ha: 1 or 2.
    #[arg(long)]
    pub accel_filter_order: Option<u8>,
}

impl AccelArgs {
    /// Applies the flags.
    pub fn apply(&self, c: &mut ControllerConfig) {
        c.kg_scaling |= self.kg_scaling;
        set(&mut c.accel_filter_hz, self.accel_filter_hz);
        set(&mut c.accel_filter_order, self.accel_filter_order);
    }
}

/// The feedback controller.
#[derive(Args, Debug, Clone)]
pub struct ControllerArgs {
    /// Controller.
    #[arg(long, value_parser = choice::<ControllerKind>())]
    pub controller: Option<ControllerKind>,
    /// Acceleration feedback gain Ka (V/V), for --controller accel.
    #[arg(value_parser = crate::args::finite, long)]
    pub ka: Option<f64>,
    /// Controller file for --controller ss (relative to the working directory).
    #[arg(long)]
    pub ss_file: Option<PathBuf>,
    /// Run anyway: a controller (file or tuned gains) made for another plant or rate, (servo
    /// run --pil) a target that cannot hold the servo rate, to measure its cost, or (servo run
    /// --hil --realtime) a host that stalls longer than the loop survives.
    #[arg(long)]
    pub force: bool,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub accel: AccelArgs,
}

impl ControllerArgs {
    /// Applies the flags.
    pub fn apply(&self, c: &mut ControllerConfig) {
        set(&mut c.kind, self.controller);
        set(&mut c.ka, self.ka);
        if let Some(p) = &self.ss_file {
            c.ss_file = Some(std::env::current_dir().map_or(p.clone(), |d| d.join(p)));
        }
        c.force |= self.force;
        self.accel.apply(c);
    }
}

/// Feedforward from the reference.
#[derive(Args, Debug, Clone)]
pub struct FeedforwardArgs {
    /// Feedforward from the reference.
    #[arg(long, value_parser = choice::<FeedforwardKind>())]
    pub feedforward: Option<FeedforwardKind>,
    /// Zero-phase smoothing of the previewed reference in Hz (Hann window; 0 = off), for
    /// surfaces with kinks or steps.
    #[arg(value_parser = crate::args::finite, long)]
    pub smoothing_hz: Option<f64>,
    /// A measured open-loop FRF of the stage (`servo frf --loop open` writes frf.csv): what
    /// `--feedforward fir` is fitted to.
    #[arg(long, value_name = "FRF_CSV")]
    pub frf: Option<PathBuf>,
}

impl FeedforwardArgs {
    /// Applies the flags; `config_file` is the configuration file the paths in `c` are
    /// resolved against.
    pub fn apply(&self, c: &mut ControllerConfig, config_file: Option<&Path>) {
        set(&mut c.feedforward, self.feedforward);
        set(&mut c.smoothing_hz, self.smoothing_hz);
        if let Some(path) = &self.frf {
            c.frf_file = Some(from_working_dir(path, config_file));
        }
    }
}

/// The stage, the controller and its feedforward: what every closed loop is made of.
#[derive(Args, Debug, Clone)]
pub struct LoopArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub plant: PlantArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub controller: ControllerArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub feedforward: FeedforwardArgs,
}

impl LoopArgs {
    /// The configuration with these flags applied.
    pub fn load(&self) -> Result<Loaded, ConfigError> {
        let mut l = self.plant.load()?;
        self.controller.apply(&mut l.config.controller);
        self.feedforward
            .apply(&mut l.config.controller, l.origin.path.as_deref());
        Ok(l)
    }
}

/// A cut of a prescription planned as `servo toolpath`, `servo measure` and `servo compensate`
/// plan it: the stage, the controller, the feedforward and the spindle speed.
#[derive(Args, Debug)]
pub struct PrescriptionCutArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub closed_loop: LoopArgs,
    /// Spindle speed in rpm (default: the configured one).
    #[arg(value_parser = crate::args::finite, long)]
    pub rpm: Option<f64>,
}

impl PrescriptionCutArgs {
    /// The plan of the configuration with these flags applied.
    pub fn plan(&self) -> Result<runner::Plan, crate::output::CliError> {
        let mut l = self.closed_loop.load()?;
        if let run_config::Scenario::Machine(m) = &mut l.config.scenario {
            set(&mut m.spindle_rpm, self.rpm);
        }
        Ok(runner::Plan::new(&l)?)
    }
}

/// A path given on the command line, which names a file from the working directory: as given
/// where the configuration's paths are resolved there too (no file, or a file in this folder),
/// else made absolute, so the configuration file's folder does not move it.
fn from_working_dir(path: &Path, config_file: Option<&Path>) -> PathBuf {
    let resolved_here = config_file
        .and_then(Path::parent)
        .is_none_or(|folder| folder.as_os_str().is_empty());
    if resolved_here || path.is_absolute() {
        return path.to_owned();
    }
    std::path::absolute(path).unwrap_or_else(|_| path.to_owned())
}

/// What the stage is asked to do.
#[derive(Args, Debug, Clone)]
pub struct ScenarioArgs {
    /// Scenario.
    #[arg(long, value_parser = choice::<ScenarioKind>())]
    pub scenario: Option<ScenarioKind>,
    /// Reference amplitude in m (sine, step, chirp).
    #[arg(value_parser = crate::args::finite, long)]
    pub amplitude: Option<f64>,
    /// Sine frequency, or chirp start frequency, in Hz.
    #[arg(value_parser = crate::args::finite, long)]
    pub frequency: Option<f64>,
    /// Chirp end frequency in Hz.
    #[arg(value_parser = crate::args::finite, long)]
    pub f_end: Option<f64>,
    /// Cutting force in N (intermittent-cut).
    #[arg(value_parser = crate::args::finite, long)]
    pub cut_force: Option<f64>,
    /// Spindle speed in rpm (intermittent-cut, machine).
    #[arg(value_parser = crate::args::finite, long)]
    pub rpm: Option<f64>,
}

impl ScenarioArgs {
    /// Applies the flags (after the run length: a step sits at 20 % of the run).
    pub fn apply(&self, l: &mut Loaded) {
        let c = &mut l.config;
        if let Some(kind) = self.scenario {
            let values = ScenarioValues {
                amplitude_m: self.amplitude,
                frequency_hz: self.frequency,
                f_end_hz: self.f_end,
                force_n: self.cut_force,
                spindle_rpm: self.rpm,
            };
            c.scenario = kind.scenario(&values, c.run.duration_s);
        }
        if let run_config::Scenario::Machine(m) = &mut c.scenario {
            set(&mut m.spindle_rpm, self.rpm);
        }
    }
}

/// Everything that describes one closed-loop run (`run`, `config` and the HIL processes).
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    #[command(flatten)]
    #[allow(missing_docs)]
    pub closed_loop: LoopArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub length: RunLengthArgs,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub scenario: ScenarioArgs,
}

impl RunArgs {
    /// The run's configuration.
    pub fn load(&self) -> Result<Loaded, ConfigError> {
        let mut l = self.closed_loop.load()?;
        self.length.apply(&mut l);
        self.scenario.apply(&mut l);
        Ok(l)
    }
}

/// The `[controller]` table of config file `path` (`--controller-from`: e.g. the pid.toml
/// `servo tune` writes), its controller file resolved against the file's folder.
pub fn controller_from(
    path: &std::path::Path,
) -> Result<run_config::ControllerConfig, ConfigError> {
    let l = Loaded::from_file(path)?;
    let mut c = l.config.controller;
    c.ss_file = c.ss_file.map(|f| l.origin.resolve(&f));
    Ok(c)
}

/// Overrides `field` with a command-line `flag` when one was given.
pub fn set<T>(field: &mut T, flag: Option<T>) {
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

/// The default recording of `servo run` and the HIL recorder.
pub const DEFAULT_RECORDING: &str = "run.mcap";

/// Where a run's recording and summary go.
#[derive(Args, Debug, Clone)]
pub struct RecordingArgs {
    /// Output MCAP file (default: run.mcap; `servo machine`: inside --out-dir). Written as
    /// `<name>.<pid>.partial` and renamed when finished.
    #[arg(short, long)]
    pub out: Option<PathBuf>,
    /// Replace an existing output file (otherwise the run does not start).
    #[arg(long, conflicts_with = "no_record")]
    pub overwrite: bool,
    /// Log time of the run's t = 0 in the recording: an RFC 3339 date
    /// (2026-01-01T00:00:00Z, the default, fixed so a seeded run's bytes repeat) or `now`.
    /// Foxglove shows log times as dates.
    #[arg(long, value_name = "DATE|now", value_parser = parse_epoch, conflicts_with = "no_record")]
    pub log_epoch: Option<u64>,
    /// Record only every n-th tick at full rate (the first, then every n), for long runs:
    /// divides the recording's size and writing time by about n. The 1 kHz `/overview`
    /// channel still summarises every tick. 1 = all (the default); at most 1 000 000.
    #[arg(long, value_name = "N", default_value_t = NonZeroU32::MIN,
          value_parser = parse_every, conflicts_with = "no_record")]
    pub record_every: NonZeroU32,
    /// Write the recording in parts, one per SECONDS of run time, for runs too long for one
    /// file: run.mcap → run_00000.mcap, run_00001.mcap, …, each a whole MCAP file moved into
    /// place as soon as the run passes its end (to be checked, copied or removed while the
    /// run goes on). From 0.001 to 1e6 s.
    #[arg(long, value_name = "SECONDS", value_parser = parse_split, conflicts_with = "no_record")]
    pub split_s: Option<NonZeroU64>,
    /// Do not write a file (summary only).
    #[arg(long)]
    pub no_record: bool,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
}

impl RecordingArgs {
    /// The recording to write, if any (to `default` when --out is not given).
    pub fn out(&self, default: &std::path::Path) -> Option<runner::recording::Target> {
        (!self.no_record).then(|| runner::recording::Target {
            path: self.out.clone().unwrap_or_else(|| default.to_owned()),
            overwrite: self.overwrite,
            epoch_ns: self.log_epoch.unwrap_or(recorder::DEFAULT_EPOCH_NS),
            every: self.record_every,
            split_ns: self.split_s,
        })
    }
}

/// Every number flag: a finite number (NaN and ±inf are refused before any command sees them).
pub fn finite(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(format!("{s}: not a finite number")),
        Err(e) => Err(format!("{s}: {e}")),
    }
}

/// A flag that must be a finite number above zero.
pub fn positive(s: &str) -> Result<f64, String> {
    finite(s).and_then(|v| {
        if v > 0.0 {
            Ok(v)
        } else {
            Err(format!("{s}: must be > 0"))
        }
    })
}

/// `--record-every`: 1 … 1 000 000.
fn parse_every(s: &str) -> Result<NonZeroU32, String> {
    s.parse::<u32>()
        .ok()
        .filter(|n| (1..=1_000_000).contains(n))
        .and_then(NonZeroU32::new)
        .ok_or_else(|| format!("{s}: expected a whole number of ticks from 1 to 1000000"))
}

/// `--split-s`: 0.001 … 1e6 s of run time, as ns.
fn parse_split(s: &str) -> Result<NonZeroU64, String> {
    finite(s)
        .ok()
        .filter(|v| (1e-3..=1e6).contains(v))
        .and_then(|v| NonZeroU64::new((v * 1e9).round() as u64))
        .ok_or_else(|| format!("{s}: expected seconds of run time from 0.001 to 1000000"))
}

/// `--log-epoch`: an RFC 3339 date or `now`, as ns since the Unix epoch.
pub fn parse_epoch(s: &str) -> Result<u64, String> {
    let when = if s == "now" {
        std::time::SystemTime::now()
    } else {
        humantime::parse_rfc3339_weak(s).map_err(|e| {
            format!("{e}: expected an RFC 3339 date such as 2026-01-01T00:00:00Z, or `now`")
        })?
    };
    when.duration_since(std::time::UNIX_EPOCH)
        .ok()
        .and_then(|d| u64::try_from(d.as_nanos()).ok())
        .ok_or_else(|| format!("{s}: must lie between 1970 and 2554"))
}

/// Options of the HIL processes.
#[derive(Args, Debug, Clone)]
pub struct HilArgs {
    /// Run prefix of the iceoryx2 services (`fts-servo/<prefix>/…`): runs with different
    /// prefixes never interfere. `servo run --hil` picks `run-<pid>`.
    #[arg(long)]
    pub prefix: Option<String>,
    /// Pace ticks to the wall clock at the servo rate (late commands are overruns; the DAC
    /// holds its last value). Default: lockstep, as fast as possible, bit-identical to `servo run`.
    #[arg(long, conflicts_with = "lockstep")]
    pub realtime: bool,
    /// Lockstep pacing (the default).
    #[arg(long)]
    pub lockstep: bool,
    #[command(flatten)]
    #[allow(missing_docs)]
    pub realtime_settings: RealtimeArgs,
}

/// Scheduling policies (`[realtime] policy`).
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum RtPolicy {
    /// SCHED_OTHER (no privilege).
    Other,
    /// SCHED_FIFO.
    Fifo,
    /// SCHED_RR.
    Rr,
}

impl RtPolicy {
    /// The policy.
    pub fn policy(self) -> daq_io::realtime::Policy {
        match self {
            RtPolicy::Other => daq_io::realtime::Policy::Other,
            RtPolicy::Fifo => daq_io::realtime::Policy::Fifo,
            RtPolicy::Rr => daq_io::realtime::Policy::Rr,
        }
    }
}

/// Real-time settings of the HIL processes (each flag sets its `[realtime]` key).
#[derive(Args, Debug, Clone)]
pub struct RealtimeArgs {
    /// Scheduling policy of plant and controller (fifo/rr need CAP_SYS_NICE or RLIMIT_RTPRIO).
    #[arg(long, value_enum)]
    pub rt_policy: Option<RtPolicy>,
    /// Real-time priority for fifo/rr, 1..=98.
    #[arg(long)]
    pub rt_priority: Option<i32>,
    /// CPU of the plant process.
    #[arg(long)]
    pub plant_cpu: Option<usize>,
    /// CPU of the controller process.
    #[arg(long)]
    pub controller_cpu: Option<usize>,
    /// Lock the servo processes' memory (mlockall) and pre-fault their stacks.
    #[arg(long)]
    pub lock_memory: bool,
    /// How plant and controller wait for each tick.
    #[arg(long, value_parser = choice::<run_config::WaitKind>())]
    pub wait: Option<run_config::WaitKind>,
    /// With --wait sleep-spin: spin this long before each tick, µs.
    #[arg(value_parser = crate::args::finite, long)]
    pub spin_margin_us: Option<f64>,
    /// Startup grace window, ms (overruns not charged to the budget).
    #[arg(value_parser = crate::args::finite, long)]
    pub grace_ms: Option<f64>,
    /// Overrun budget: sustained fraction of late ticks absorbed (0..1).
    #[arg(value_parser = crate::args::finite, long)]
    pub overrun_rate: Option<f64>,
    /// Overrun budget: burst of overruns beyond the sustained rate absorbed at once, ms.
    #[arg(value_parser = crate::args::finite, long)]
    pub overrun_burst_ms: Option<f64>,
}

impl RealtimeArgs {
    /// Applies the flags to `[realtime]`.
    pub fn apply(&self, l: &mut Loaded) {
        let r = &mut l.config.realtime;
        set(&mut r.policy, self.rt_policy.map(RtPolicy::policy));
        set(&mut r.priority, self.rt_priority);
        if self.plant_cpu.is_some() {
            r.plant_cpu = self.plant_cpu;
        }
        if self.controller_cpu.is_some() {
            r.controller_cpu = self.controller_cpu;
        }
        r.lock_memory |= self.lock_memory;
        set(&mut r.wait, self.wait);
        set(&mut r.spin_margin_s, self.spin_margin_us.map(|u| u * 1e-6));
        set(&mut r.grace_s, self.grace_ms.map(|m| m * 1e-3));
        set(&mut r.overrun_rate, self.overrun_rate);
        set(
            &mut r.overrun_burst_s,
            self.overrun_burst_ms.map(|m| m * 1e-3),
        );
    }
}

impl HilArgs {
    /// The configuration of `run` with these flags' `[realtime]` settings on top.
    pub fn load(&self, run: &RunArgs) -> Result<Loaded, ConfigError> {
        let mut l = run.load()?;
        self.realtime_settings.apply(&mut l);
        Ok(l)
    }

    /// Lockstep or real time.
    pub fn pacing(&self) -> daq_io::serve::Pacing {
        if self.realtime {
            daq_io::serve::Pacing::RealTime
        } else {
            daq_io::serve::Pacing::Lockstep
        }
    }

    /// The run prefix a HIL process joins (required there).
    pub fn prefix(&self) -> Result<String, ConfigError> {
        self.prefix.clone().ok_or_else(|| {
            run_config::Origin::default().invalid(
                "--prefix",
                "(missing)",
                "the run's service prefix, e.g. --prefix bench",
            )
        })
    }
}

/// How long the plant waits for a silent controller before the safe state.
#[derive(Args, Debug, Clone)]
pub struct PeerTimeoutArgs {
    /// Controller silence after which the plant declares it lost and drives zero current, ms
    /// (default 200 lockstep; real time: [realtime] peer_timeout_s, 0.5 ms; > 0).
    #[arg(value_parser = crate::args::finite, long)]
    pub peer_timeout_ms: Option<f64>,
}

impl PeerTimeoutArgs {
    /// The timeout, checked.
    pub fn timeout(&self) -> Result<Option<std::time::Duration>, ConfigError> {
        match self.peer_timeout_ms {
            Some(t) if !(t > 0.0 && t < 1e7) => {
                Err(run_config::Origin::default().invalid("--peer-timeout-ms", t, "0 < t < 1e7 ms"))
            }
            t => Ok(t.map(|t| std::time::Duration::from_secs_f64(t * 1e-3))),
        }
    }
}
