//! Replaying a recording: the run rebuilt from what the file holds (its configuration, seed
//! and embedded input files), run again — as it was, to show that it reproduces, or with a
//! replaced controller, feedforward or plant, to show what the run would have been — and the
//! two compared: data channels by digest, metrics side by side.

use crate::operator_log::OperatorLog;
use crate::plan::{Plan, CONTROLLER_INPUT, DEPLOYMENT_INPUT};
use crate::recording::{inspect_with, FrameSink, RunHeader};
use crate::run::{run_with, RunOptions};
use crate::summary::Summary;
use crate::RunError;
use plant_sim::PlantParams;
use recorder::Frame;
use run_config::RunConfig;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Frames per digest block: a difference is located to within this many recorded frames.
pub const DIGEST_BLOCK: u64 = 4096;

/// SHA-256 digests of the data channels (every telemetry and truth value, bit for bit) of
/// consecutive blocks of [`DIGEST_BLOCK`] frames, up to a limit.
#[derive(Debug, Clone)]
pub struct FrameDigest {
    limit: u64,
    frames: u64,
    block: Sha256,
    blocks: Vec<[u8; 32]>,
}

impl FrameDigest {
    /// Digests of the first `limit` frames shown.
    pub fn new(limit: u64) -> Self {
        FrameDigest {
            limit,
            frames: 0,
            block: Sha256::new(),
            blocks: Vec::new(),
        }
    }

    /// Takes the next frame (ignored past the limit).
    pub fn add(&mut self, f: &Frame) {
        if self.frames >= self.limit {
            return;
        }
        for v in f.telemetry.values().iter().chain(&f.truth.values()) {
            self.block.update(v.to_bits().to_le_bytes());
        }
        self.frames += 1;
        if self.frames.is_multiple_of(DIGEST_BLOCK) {
            self.blocks.push(self.block.finalize_reset().into());
        }
    }

    /// Frames digested.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The block digests, the last one partial.
    fn finish(mut self) -> Vec<[u8; 32]> {
        if !self.frames.is_multiple_of(DIGEST_BLOCK) {
            self.blocks.push(self.block.finalize().into());
        }
        self.blocks
    }

    /// The first frame (index among those digested) from which `self` and `other` may differ,
    /// or `None` when both digested the same frames with the same values.
    pub fn first_difference(self, other: FrameDigest) -> Option<u64> {
        let shorter = self.frames.min(other.frames);
        let same_count = self.frames == other.frames;
        let (a, b) = (self.finish(), other.finish());
        match a.iter().zip(&b).position(|(x, y)| x != y) {
            Some(block) => Some(block as u64 * DIGEST_BLOCK),
            None if same_count => None,
            None => Some(shorter),
        }
    }
}

/// What a recording holds for a replay, read in one pass ([`FrameSink`] for
/// [`crate::recording::inspect_with`]): its header, the digest of its frames (up to a limit),
/// and whether its frames carry a simulator's truth (a hardware run's do not).
pub struct Recorded {
    /// Frames digested at most (those before an operator's first change — a controller swap,
    /// a gain change — which a replay does not repeat).
    pub limit: u64,
    /// The run header (configuration, controller, inputs, decimation).
    pub header: Option<RunHeader>,
    /// Digest of every recorded frame.
    pub digest: Option<FrameDigest>,
    /// Whether any frame carried simulator truth (tool position or gap not zero).
    pub has_truth: bool,
}

impl Recorded {
    /// Reads a recording, digesting its first `limit` frames.
    pub fn new(limit: u64) -> Self {
        Recorded {
            limit,
            header: None,
            digest: None,
            has_truth: false,
        }
    }
}

impl FrameSink for Recorded {
    fn header(&mut self, header: &RunHeader) -> Result<(), RunError> {
        self.header = Some(header.clone());
        self.digest = Some(FrameDigest::new(self.limit));
        Ok(())
    }

    fn frame(&mut self, f: &Frame) {
        if let Some(d) = &mut self.digest {
            d.add(f);
        }
        self.has_truth |= f.truth.tool_m != 0.0 || f.truth.gap_m != 0.0;
    }
}

impl RunHeader {
    /// The recorded run with `config` instead of the recorded configuration (a replaced
    /// controller, feedforward or plant): the embedded input files are used where the
    /// configuration still names them, so an unchanged controller file is the recorded copy
    /// and a new one is read from disk. The recorded deployment runs as long as the
    /// configuration is the recorded one (its duration aside).
    pub fn replan(&self, config: RunConfig) -> Result<Plan, RunError> {
        let recorded = &self.loaded.config;
        let same_controller_file = config.controller.ss_file == recorded.controller.ss_file;
        let mut same_loop = config.clone();
        same_loop.run.duration_s = recorded.run.duration_s;
        let same_loop = same_loop == *recorded;
        let mut loaded = self.loaded.clone();
        loaded.config = config;
        let inputs = self
            .inputs()
            .into_iter()
            .filter(|i| same_controller_file || i.name != CONTROLLER_INPUT)
            .filter(|i| same_loop || i.name != DEPLOYMENT_INPUT)
            .collect();
        Plan::with_inputs(&loaded, inputs)
    }
}

/// A recording opened for a replay: what it holds, and the configuration the replay runs —
/// the recorded one, unless changed through [`Replay::config_mut`] (a controller, a
/// feedforward) or [`Replay::replace_plant`].
pub struct Replay {
    file: PathBuf,
    header: RunHeader,
    recorded_digest: FrameDigest,
    recorded: Summary,
    recorded_s: f64,
    has_truth: bool,
    steered_at: Option<u64>,
    config: RunConfig,
    plant_replaced: bool,
}

/// What a replay found: the data channels compared bit for bit (when every tick was
/// recorded), the recorded and replayed metrics.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ReplayReport {
    /// The configuration differs from the recorded one.
    pub changed: bool,
    /// Frames whose data channels were compared.
    pub frames_compared: u64,
    /// Every compared frame is identical, bit for bit (None: not compared, the recording
    /// holds every n-th tick).
    pub identical: Option<bool>,
    /// The first frame of the first [`DIGEST_BLOCK`] that differs.
    pub first_difference_frame: Option<u64>,
    /// The tick of an operator's first change (`servo ctl load / gain`): frames from there on
    /// are not compared, the replay runs the recorded configuration throughout.
    pub compared_until_operator_tick: Option<u64>,
    /// The recording's summary, recomputed from its frames.
    pub recorded: Summary,
    /// The replay's summary.
    pub replayed: Summary,
    /// The recorded deployment, which the replay ran, beside the one this machine designs
    /// from the recorded configuration (None when the configuration was changed).
    pub design: Option<RecordedDesign>,
    /// The recording's decimation: every n-th tick recorded.
    #[serde(skip)]
    pub every: u32,
    /// The replay's loop rate, Hz.
    #[serde(skip)]
    pub rate_hz: f64,
}

/// The deployment a recording carries beside the one this machine designs from its
/// configuration.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RecordedDesign {
    /// Designed here to the same bits.
    Same,
    /// Designed here up to this relative difference apart: another processor's vector
    /// instructions round the eigenvalue-based designs otherwise.
    Apart(f64),
    /// Designed here in another form: a recording of another version of the design.
    OtherForm,
    /// The recording carries no deployment (an older recording): designed again.
    NotRecorded,
}

impl RecordedDesign {
    fn of(difference: Option<f64>) -> Self {
        match difference {
            None => RecordedDesign::NotRecorded,
            Some(0.0) => RecordedDesign::Same,
            Some(d) if d.is_finite() => RecordedDesign::Apart(d),
            Some(_) => RecordedDesign::OtherForm,
        }
    }
}

impl Replay {
    /// Opens the recording at `file` for a replay: read whole and checked (with `salvage`, as
    /// far as it is intact), its frames digested up to an operator's first change.
    pub fn open(file: &Path, salvage: bool) -> Result<Replay, RunError> {
        // A replay runs the configuration alone: an operator's first change (a controller
        // swap, a gain change) ends the part it can reproduce.
        let steered_at = OperatorLog::read(file)?.first_tick();
        let mut rec = Recorded::new(steered_at.unwrap_or(u64::MAX));
        let inspected = inspect_with(file, &mut rec)?.intact(file, salvage)?;
        let part = inspected
            .end
            .get(recorder::PART_KEY)
            .and_then(|p| p.parse().ok());
        if let Some(part @ 1..) = part {
            let first = recorder::first_part_of(file)
                .map_or_else(|| "its `_00000.mcap`".into(), |f| f.display().to_string());
            return Err(RunError::LaterPart {
                path: file.to_owned(),
                part,
                first,
            });
        }
        let (Some(header), Some(recorded_digest)) = (rec.header, rec.digest) else {
            return Err(RunError::NotARun(file.to_owned()));
        };
        Ok(Replay {
            file: file.to_owned(),
            config: header.loaded.config.clone(),
            header,
            recorded_digest,
            recorded: inspected.summary,
            recorded_s: inspected.read.last_time_ns.map_or(0.0, |t| t as f64 * 1e-9),
            has_truth: rec.has_truth,
            steered_at,
            plant_replaced: false,
        })
    }

    /// The configuration the replay runs, to change its controller or feedforward.
    pub fn config_mut(&mut self) -> &mut RunConfig {
        &mut self.config
    }

    /// Replays on `plant` instead of the recorded stage (a recording of a DAQ daemon or a real
    /// stage has no simulator truth to re-run: it replays only on a plant model).
    pub fn replace_plant(&mut self, plant: PlantParams) {
        self.config.plant = plant;
        self.plant_replaced = true;
    }

    /// Runs the replay with `opts` (recording, stop, progress) and compares it with the
    /// recording.
    pub fn run(self, opts: RunOptions<'_>) -> Result<ReplayReport, RunError> {
        if !self.plant_replaced && !self.has_truth {
            return Err(RunError::NoTruth(self.file));
        }
        let mut config = self.config;
        let changed = config != self.header.loaded.config;
        // As long as the recording: a run stopped early (`servo ctl stop`, a signal) replays
        // to where it stopped, not to its configured duration.
        if self.recorded_s > 0.0 && self.recorded_s < config.run.duration_s {
            config.run.duration_s = self.recorded_s;
        }
        let plan = self.header.replan(config)?;
        let every = self.header.every.get();
        let frames = self.recorded_digest.frames();
        let mut digest = FrameDigest::new(frames);
        let replayed = run_with(&plan, opts, |f| digest.add(f))?;
        let difference =
            (every == 1).then(|| self.recorded_digest.clone().first_difference(digest));
        Ok(ReplayReport {
            changed,
            frames_compared: if difference.is_some() { frames } else { 0 },
            identical: difference.map(|d| d.is_none()),
            first_difference_frame: difference.flatten(),
            compared_until_operator_tick: self.steered_at,
            recorded: self.recorded,
            replayed,
            design: (!changed).then(|| RecordedDesign::of(plan.design_difference)),
            every,
            rate_hz: plan.config.plant.timing.servo_rate_hz,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(k: u64) -> Frame {
        let mut f = Frame::default();
        f.telemetry.following_error_m = k as f32 * 1e-9;
        f.truth.tool_m = -(k as f32) * 1e-9;
        f
    }

    #[test]
    fn digests_locate_the_first_differing_block() {
        let n = 3 * DIGEST_BLOCK + 17;
        let digest = |change: Option<u64>| {
            let mut d = FrameDigest::new(u64::MAX);
            for k in 0..n {
                let mut f = frame(k);
                if Some(k) == change {
                    // One bit of one value.
                    f.truth.gap_m = f32::from_bits(1);
                }
                d.add(&f);
            }
            d
        };
        assert_eq!(digest(None).first_difference(digest(None)), None);
        for k in [0, DIGEST_BLOCK - 1, 2 * DIGEST_BLOCK + 5, n - 1] {
            let at = digest(None).first_difference(digest(Some(k)));
            assert_eq!(at, Some(k / DIGEST_BLOCK * DIGEST_BLOCK), "change at {k}");
        }
        // A shorter run differs from its last (partial) block; a limit cuts the longer one to
        // match.
        let mut short = FrameDigest::new(u64::MAX);
        let mut limited = FrameDigest::new(DIGEST_BLOCK + 3);
        for k in 0..DIGEST_BLOCK + 3 {
            short.add(&frame(k));
        }
        assert_eq!(
            digest(None).first_difference(short.clone()),
            Some(DIGEST_BLOCK)
        );
        for k in 0..n {
            limited.add(&frame(k));
        }
        assert_eq!(limited.frames(), DIGEST_BLOCK + 3);
        assert_eq!(short.first_difference(limited), None);
    }
}
