//! What a run's recording carries, and reading it back in one streaming pass.
//!
//! The `run` metadata record holds the resolved configuration, the controller, the version,
//! seed, rate and statistics window, and the SHA-256 of every input file; the inputs
//! themselves are attachments. A recording is therefore self-contained: reading it never
//! opens a path named inside it.

use crate::error::RunError;
use crate::plan::Plan;
use crate::stop::EndReason;
use crate::summary::{RunMeta, Summary, SummaryBuilder};
use recorder::{FileState, Frame, Overwrite, ReadReport, RecordOptions, Recorder, Visit};
use run_config::sha256_hex;
use run_config::{ConfigError, Loaded, Origin, RunConfig};
use std::collections::BTreeMap;
use std::num::{NonZeroU32, NonZeroU64};
use std::path::{Path, PathBuf};

/// Where and how a run is recorded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Target {
    /// The MCAP file.
    pub path: PathBuf,
    /// Replace an existing file (otherwise the run does not start).
    pub overwrite: bool,
    /// Log time of the run's t = 0, ns since the Unix epoch
    /// ([`recorder::DEFAULT_EPOCH_NS`] unless asked).
    pub epoch_ns: u64,
    /// Full-rate decimation: every n-th tick recorded (1 = all; see
    /// [`RecordOptions::every`]).
    pub every: NonZeroU32,
    /// Run time each part of a split recording covers, ns (None: one file; see
    /// [`RecordOptions::split_ns`]).
    pub split_ns: Option<NonZeroU64>,
}

impl Target {
    /// `path`, not replacing an existing file, with the default epoch, every tick.
    pub fn new(path: impl Into<PathBuf>) -> Self {
        Target {
            path: path.into(),
            overwrite: false,
            epoch_ns: recorder::DEFAULT_EPOCH_NS,
            every: NonZeroU32::MIN,
            split_ns: None,
        }
    }

    /// The file the recording starts in: `path`, or its first part when split.
    pub fn first_file(&self) -> PathBuf {
        recorder::first_file(&self.path, self.split_ns)
    }

    /// What a run wrote, for its report: the file, or the parts' pattern and span.
    pub fn written(&self) -> String {
        match self.split_ns {
            None => self.path.display().to_string(),
            Some(span) => format!(
                "{} … (a part per {} s of run)",
                self.first_file().display(),
                span.get() as f64 * 1e-9
            ),
        }
    }

    /// How an existing file is treated.
    pub fn overwrite(&self) -> Overwrite {
        Overwrite::from_flag(self.overwrite)
    }

    /// Fails now if the recording could not be written (see [`recorder::check_target`]).
    pub fn check(&self) -> Result<(), RunError> {
        Ok(recorder::check_target(
            &self.first_file(),
            self.overwrite(),
        )?)
    }
}

/// Key of the `run` record naming how the run's dense products rounded
/// ([`servo_core::ARITHMETIC`]); recordings made before it existed fused them.
pub const ARITHMETIC_KEY: &str = "arithmetic";

/// The `run` metadata record of a run of `plan`.
pub fn metadata(plan: &Plan) -> BTreeMap<String, String> {
    let c = &plan.config;
    let mut m = BTreeMap::from([
        ("config".to_string(), c.to_toml()),
        (
            "controller".to_string(),
            plan.controller.description.clone(),
        ),
        ("seed".to_string(), c.run.seed.to_string()),
        (
            "servo_rate_hz".to_string(),
            c.plant.timing.servo_rate_hz.to_string(),
        ),
        ("settle_s".to_string(), c.run.settle().to_string()),
        (
            ARITHMETIC_KEY.to_string(),
            servo_core::ARITHMETIC.to_string(),
        ),
    ]);
    for input in &plan.inputs {
        m.insert(input_key(&input.name), sha256_hex(&input.data));
    }
    m
}

/// This host's name (`unknown` when the kernel does not say).
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map_or_else(|_| "unknown".into(), |h| h.trim().to_owned())
}

/// The `environment` record of run `run_id` (its identity on the transport): what differs
/// between two runs of the same seed (the recorder adds the start time). Comparisons of
/// recordings leave it out.
pub fn environment(run_id: u64) -> BTreeMap<String, String> {
    let host = host_name();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    BTreeMap::from([
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("host".to_string(), host),
        ("pid".to_string(), std::process::id().to_string()),
        ("run_id".to_string(), format!("{run_id:016x}")),
        (
            "simd".to_string(),
            servo_core::simd::detected().name().to_string(),
        ),
        ("command".to_string(), command),
    ])
}

/// Starts the recording of run `run_id` of `plan` at `to`: its `run` metadata, its
/// environment, its inputs as attachments.
pub fn create(plan: &Plan, to: &Target, run_id: u64) -> Result<Recorder, RunError> {
    create_with(plan, to, run_id, Vec::new())
}

/// [`create`], with `more` facts about where the run ran in its `environment` record (a PIL
/// run's target).
pub fn create_with(
    plan: &Plan,
    to: &Target,
    run_id: u64,
    more: Vec<(String, String)>,
) -> Result<Recorder, RunError> {
    let mut environment = environment(run_id);
    environment.extend(more);
    Ok(Recorder::create(
        &to.path,
        metadata(plan),
        RecordOptions {
            overwrite: to.overwrite(),
            inputs: plan.inputs.clone(),
            epoch_ns: to.epoch_ns,
            every: to.every,
            environment,
            split_ns: to.split_ns,
            ..Default::default()
        },
    )?)
}

/// The `end` record of a run of `plan` that ended for `reason` after the frames `summary` saw:
/// the reason and tick count, and after a machine-protection trip its cause, tick, what the
/// tick before it showed and the safe state.
pub fn end_record(
    plan: &Plan,
    reason: EndReason,
    summary: &SummaryBuilder,
) -> BTreeMap<String, String> {
    let ticks = summary.ticks();
    let mut m = reason.record(ticks, ticks as f64 * plan.period_s());
    if let Some(t) = summary.trip(plan.config.plant.timing.servo_rate_hz) {
        for (k, v) in [
            ("trip_cause", t.cause),
            ("trip_tick", t.tick.to_string()),
            ("trip_following_error_m", t.following_error_m.to_string()),
            ("trip_measured_m", t.measured_m.to_string()),
            ("trip_control_v", t.control_v.to_string()),
            (
                "safe_state",
                plan.config.protection.safe_state.name().to_string(),
            ),
        ] {
            m.insert(k.to_string(), v);
        }
    }
    m
}

/// The metadata key holding the SHA-256 of the input attachment `name`.
pub(crate) fn input_key(name: &str) -> String {
    format!("input.{name}.sha256")
}

/// What a recording says about its run, complete before its first frame.
#[derive(Debug, Clone)]
pub struct RunHeader {
    /// The configuration it was run with (no origin: it came from the file).
    pub loaded: Loaded,
    /// The controller's description.
    pub controller: String,
    /// The embedded input files by attachment name, each checked against its SHA-256.
    pub inputs: BTreeMap<String, Vec<u8>>,
    /// Full-rate decimation the run was recorded with (every n-th tick; 1 = all).
    pub every: NonZeroU32,
    /// Whether its telemetry pairs each tick's reference with the reading the tick acted on
    /// (contract v6); false for older recordings, which paired it with the next reading (the
    /// noise statistics agree; a moving reference's error reads one tick's motion apart).
    pub reading_used: bool,
    /// How its dense products rounded ([`servo_core::ARITHMETIC`]).
    pub arithmetic: String,
}

impl RunHeader {
    /// The recorded run rebuilt: its configuration with the embedded controller file and
    /// surface image (nothing read from disk), so its closed loop is the one that ran.
    pub fn plan(&self) -> Result<Plan, RunError> {
        Plan::with_inputs(&self.loaded, self.inputs())
    }

    /// The embedded input files, as a run takes them.
    pub fn inputs(&self) -> Vec<recorder::Input> {
        let media = |name: &str| match name {
            crate::plan::SURFACE_INPUT => "image/png",
            crate::plan::PRESCRIPTION_INPUT => "application/json",
            _ => "application/toml",
        };
        self.inputs
            .iter()
            .map(|(name, data)| recorder::Input {
                name: name.clone(),
                media_type: media(name).into(),
                data: data.clone(),
            })
            .collect()
    }
}

/// What else reads the frames of a recording in the same pass (a study's analysis).
pub trait FrameSink {
    /// Called once, before the first frame.
    fn header(&mut self, _header: &RunHeader) -> Result<(), RunError> {
        Ok(())
    }
    /// Each frame.
    fn frame(&mut self, _frame: &Frame) {}
}

/// Reading only the summary.
impl FrameSink for () {}

/// A recording read back.
#[derive(Debug, Clone)]
pub struct Inspected {
    /// The summary recomputed from the frames.
    pub summary: Summary,
    /// The `end` record: how the run ended (empty for an unfinished file).
    pub end: BTreeMap<String, String>,
    /// Whether the file was complete, and how much was read.
    pub read: ReadReport,
}

impl Inspected {
    /// `self` when the file is complete and every check passed, or when `salvage` accepts
    /// what was intact of it; a [`RunError::Damaged`] naming the file and the damage
    /// otherwise.
    pub fn intact(self, path: &Path, salvage: bool) -> Result<Self, RunError> {
        match self.damage() {
            Some(report) if !salvage => Err(RunError::Damaged {
                path: path.to_owned(),
                report,
            }),
            _ => Ok(self),
        }
    }

    /// What keeps the file from being a whole run, if anything: damage or an early end the
    /// read found, or an `end` record counting other ticks than the file holds (when every
    /// tick was recorded).
    pub fn damage(&self) -> Option<String> {
        if !self.read.is_intact() {
            return Some(self.read.to_string());
        }
        // A recording cut back after a write failure says how many it kept; a part of a
        // split one, how many it holds.
        let claimed = (self.end.get(recorder::RECORDED_TICKS_KEY))
            .or(self.end.get(recorder::PART_TICKS_KEY))
            .or(self.end.get("ticks"))
            .and_then(|t| t.parse::<u64>().ok());
        match claimed {
            Some(n) if self.summary.meta.recorded_every.is_none() && n != self.read.frames => {
                Some(format!(
                    "its end record counts {n} ticks, the file holds {}",
                    self.read.frames
                ))
            }
            _ => None,
        }
    }
}

/// Streams the recording `path` of a run (constant memory), recomputing its summary and
/// showing every frame to `sink`.
pub fn inspect_with(path: &Path, sink: &mut impl FrameSink) -> Result<Inspected, RunError> {
    let mut reader = RunReader {
        path,
        sink,
        run: None,
        end: BTreeMap::new(),
        environment: BTreeMap::new(),
        attachments: BTreeMap::new(),
        state: None,
        error: None,
    };
    let read = recorder::stream(path, &mut reader)?;
    if let Some(e) = reader.error {
        return Err(e);
    }
    let (header, builder) = match reader.state {
        Some(state) => state,
        None => {
            let header = reader.header()?;
            let builder = SummaryBuilder::new(header.loaded.config.run.settle());
            reader.sink.header(&header)?;
            (header, builder)
        }
    };
    let cfg = &header.loaded.config;
    let end = reader.end;
    let target = crate::pil::TargetMeta::from_records(&reader.environment, &end);
    let completed = end.get("reason").is_some_and(|r| r == "completed");
    let every = header.every.get();
    let summary = builder.finish(RunMeta {
        interrupted: !completed || builder.ticks() < cfg.ticks().div_ceil(u64::from(every)),
        recorded_every: (every > 1).then_some(every),
        recorded_messages: Some(read.messages),
        arithmetic: header.arithmetic.clone(),
        end_reason: Some(match read.state {
            FileState::Finished => end
                .get("reason")
                .cloned()
                .unwrap_or_else(|| "unknown".into()),
            _ => "unfinished".into(),
        }),
        target,
        ..RunMeta::of(cfg, header.controller.clone())
    });
    Ok(Inspected { summary, end, read })
}

/// Recomputes the summary of the recording `path`.
pub fn inspect(path: &Path) -> Result<Inspected, RunError> {
    inspect_with(path, &mut ())
}

/// The configuration a recording embeds, parsed and checked as strictly as a configuration
/// file: every value in its range before anything uses it (errors name the recording and the
/// key).
fn embedded_config(path: &Path, text: &str) -> Result<RunConfig, RunError> {
    let config: RunConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: servo_config::toml_message(text, &e),
    })?;
    config.validate(&Origin {
        path: Some(format!("{} (its configuration)", path.display()).into()),
        text: Some(text.to_owned()),
    })?;
    Ok(config)
}

/// Checks the configuration a finished recording embeds (found through its summary, without
/// streaming the file); a file whose summary cannot be read, or without a `run` record, is
/// left to the read that follows (which reports the damage).
pub fn check_embedded_config(path: &Path) -> Result<(), RunError> {
    #[derive(Default)]
    struct Run(Option<String>);
    impl Visit for Run {
        fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
            if name == "run" {
                self.0 = values.get("config").cloned();
            }
        }
    }
    let mut run = Run::default();
    if let (Ok(true), Some(text)) = (recorder::visit_indexed(path, &mut run), &run.0) {
        embedded_config(path, text)?;
    }
    Ok(())
}

/// The [`Visit`]or behind [`inspect_with`].
struct RunReader<'a, S: FrameSink> {
    path: &'a Path,
    sink: &'a mut S,
    run: Option<BTreeMap<String, String>>,
    end: BTreeMap<String, String>,
    /// The `environment` record (where the run ran).
    environment: BTreeMap<String, String>,
    attachments: BTreeMap<String, Vec<u8>>,
    state: Option<(RunHeader, SummaryBuilder)>,
    error: Option<RunError>,
}

impl<S: FrameSink> RunReader<'_, S> {
    /// The header from the `run` record and the attachments read so far (taken: it is built
    /// once, before the first frame or at the end of a file without frames).
    fn header(&mut self) -> Result<RunHeader, RunError> {
        let not_a_run = || RunError::NotARun(self.path.to_owned());
        let run = self.run.as_ref().ok_or_else(not_a_run)?;
        let text = run.get("config").ok_or_else(not_a_run)?;
        let config = embedded_config(self.path, text)?;
        for (name, data) in &self.attachments {
            if run.get(&input_key(name)) != Some(&sha256_hex(data)) {
                return Err(RunError::InputMismatch {
                    path: self.path.to_owned(),
                    input: name.clone(),
                });
            }
        }
        let inputs = std::mem::take(&mut self.attachments);
        // Recordings made before decimation existed have no key: every tick.
        let every = match run.get(recorder::EVERY_KEY) {
            None => NonZeroU32::MIN,
            Some(v) => v
                .parse()
                .map_err(|_| RunError::NotARun(self.path.to_owned()))?,
        };
        Ok(RunHeader {
            every,
            reading_used: run.get(recorder::TELEMETRY_KEY).map(String::as_str)
                == Some(recorder::TELEMETRY_READING_USED),
            arithmetic: run
                .get(ARITHMETIC_KEY)
                .cloned()
                .unwrap_or_else(|| servo_core::FUSED_ARITHMETIC.into()),
            controller: run
                .get("controller")
                .cloned()
                .unwrap_or_else(|| format!("{:?}", config.controller.kind)),
            loaded: Loaded {
                config,
                origin: Default::default(),
            },
            inputs,
        })
    }
}

impl<S: FrameSink> Visit for RunReader<'_, S> {
    fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
        match name {
            "run" => self.run = Some(values.clone()),
            "end" => self.end = values.clone(),
            "environment" => self.environment = values.clone(),
            _ => {}
        }
    }

    fn attachment(&mut self, name: &str, data: &[u8]) {
        self.attachments.insert(name.to_owned(), data.to_vec());
    }

    fn frame(&mut self, frame: &Frame) {
        if self.error.is_some() {
            return;
        }
        if self.state.is_none() {
            let started = self.header().and_then(|h| {
                self.sink.header(&h)?;
                let builder = SummaryBuilder::new(h.loaded.config.run.settle());
                Ok((h, builder))
            });
            match started {
                Ok(s) => self.state = Some(s),
                Err(e) => {
                    self.error = Some(e);
                    return;
                }
            }
        }
        if let Some((_, builder)) = &mut self.state {
            builder.add(frame);
        }
        self.sink.frame(frame);
    }
}
