//! MCAP writing off the servo tick: the loop pushes [`Frame`]s into a preallocated wait-free
//! ring; a writer thread encodes them into whole-chunk zstd chunks with message indexes
//! ([`crate::mcap_file`]; profile `ros2`: what Foxglove's indexed reader expects), adds the
//! 1 kHz [`crate::overview`] channel, and keeps up with the loop on one core (≥ 25× real time
//! at 199.6 kHz, `cargo bench --bench recorder`).
//!
//! Log time is the run's time from a fixed epoch ([`DEFAULT_EPOCH_NS`], configurable), so a
//! seeded run gives byte-identical data channels and Foxglove shows real dates. What differs
//! between two runs of the same seed (run id, host, version, wall-clock times) is kept to the
//! `environment` metadata record (at the start) and the `timing` one (at the end).
//!
//! The file is written under a temporary name beside the target (`<name>.<pid>.partial`) and
//! renamed when finished; an existing target is kept unless [`Overwrite::Replace`] is asked
//! for. Every closed chunk reaches the operating system in one write at once, and storage
//! (`fdatasync`, on a thread of its own so the writer never waits for the disk) every
//! [`SYNC_INTERVAL`]: a run killed with SIGKILL loses at most the chunk being filled and the
//! ones still being compressed ([`CHUNK_SPAN_NS`] of run each, at most one more than the
//! compressors: one per CPU, up to 4) and what waits in the ring; a power loss at most
//! [`SYNC_INTERVAL`] and one sync's duration more. The reader recovers the rest.

use crate::error::{Kept, RecordError};
use crate::frame::{Frame, Message, TelemetryRecord, TruthRecord};
use crate::mcap_file::McapFile;
use crate::overview::{Overview, OverviewBin};
use crate::placement::{check_target, create_private, partial_path, publish, Overwrite};
use crate::room::Room;
use crate::syncer::Syncer;
use std::collections::BTreeMap;
use std::fs::File;
use std::num::{NonZeroU32, NonZeroU64};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime};

/// A file a run depended on, embedded in its recording (MCAP attachment) so the recording
/// replays and inspects on its own.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Input {
    /// Attachment name (e.g. `controller.toml`, `surface.png`).
    pub name: String,
    /// Media type (`application/toml`, `image/png`).
    pub media_type: String,
    /// The bytes.
    pub data: Vec<u8>,
}

/// How a recording is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RecordOptions {
    /// Ring full: wait or drop.
    pub when_full: WhenFull,
    /// Existing target.
    pub overwrite: Overwrite,
    /// Files embedded as attachments, before the first message.
    pub inputs: Vec<Input>,
    /// Log time of the run's t = 0, ns since the Unix epoch (Foxglove shows log times as
    /// dates). Kept in the `run` record as `log_time_epoch_ns`; readers subtract it.
    pub epoch_ns: u64,
    /// Decimation of the full-rate channels for long runs: every `every`-th tick is recorded
    /// (the first tick, then every `every` ticks; 1 = all). The `/overview` channel still sees
    /// every tick. Kept in the `run` record as `record_every`. At least 1.
    pub every: NonZeroU32,
    /// The `environment` record: what differs between two runs of the same seed (run id,
    /// host, version, …). The recorder adds `started` (UTC).
    pub environment: BTreeMap<String, String>,
    /// Run time each part of the recording covers, ns (None: one file). A split recording is
    /// written as numbered parts ([`part_path`]: `<stem>_00000.mcap`, `<stem>_00001.mcap`, …),
    /// each a whole MCAP file with the opening records and attachments, finished and moved
    /// into place when the run passes its end, so a long run can be read, checked and removed
    /// part by part while it goes on. Message sequence numbers run on across parts; each
    /// part's `end` record says which part it is and which ticks it holds ([`PART_KEY`],
    /// [`FIRST_TICK_KEY`], [`PART_TICKS_KEY`]); the last part's is the run's own.
    pub split_ns: Option<NonZeroU64>,
}

/// The default log-time epoch: 2026-01-01T00:00:00Z, in ns since the Unix epoch (fixed, so
/// a seeded run's bytes are reproducible).
pub const DEFAULT_EPOCH_NS: u64 = 1_767_225_600_000_000_000;

impl Default for RecordOptions {
    /// Wait when full, never overwrite, nothing attached, the default epoch, every tick.
    fn default() -> Self {
        RecordOptions {
            when_full: WhenFull::Wait,
            overwrite: Overwrite::Refuse,
            inputs: Vec::new(),
            epoch_ns: DEFAULT_EPOCH_NS,
            every: NonZeroU32::MIN,
            environment: BTreeMap::new(),
            split_ns: None,
        }
    }
}

/// What to do when the ring is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WhenFull {
    /// Wait for room (simulation: nothing is lost, the run just slows down).
    Wait,
    /// Drop the frame and count it (real time: never block the loop).
    Drop,
}

/// Counts reported when a recording is finished.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RecordStats {
    /// Full-rate messages written (two per recorded frame; the overview is not counted).
    pub messages: u64,
    /// Frames dropped because the ring was full.
    pub dropped_frames: u64,
}

/// The producer side, owned by the loop.
pub struct Recorder {
    ring: rtrb::Producer<Frame>,
    when_full: WhenFull,
    dropped: u64,
    writer_alive: Arc<AtomicBool>,
    /// Where a [`WhenFull::Wait`] producer waits for the writer to make room.
    room: Arc<Room>,
    written: Arc<AtomicU64>,
    /// What follows the last frame, handed to the writer thread at [`Recorder::finish`].
    end: Arc<Mutex<Ending>>,
    /// Attachments to write with the `end` record ([`Recorder::attach`]).
    late: Vec<(Input, u64)>,
    thread: Option<JoinHandle<Result<u64, RecordError>>>,
}

/// Frames the ring holds (≈ 0.16 s at 199.6 kHz; 32 768 × 64 B ≈ 2 MB).
pub const RING_FRAMES: usize = 1 << 15;

/// Run time one full-rate chunk covers at most, ns (20 ms: ≈ 4 000 ticks, ≈ 0.5 MB before
/// compression): what a killed run loses per chunk not yet written, besides the ring.
pub const CHUNK_SPAN_NS: u64 = 20_000_000;

/// Run time one overview chunk covers at most, ns.
pub const OVERVIEW_CHUNK_SPAN_NS: u64 = 1_000_000_000;

/// Bytes of records one chunk holds at most (a bound for slow rates; at 199.6 kHz the time
/// span closes chunks first).
pub const CHUNK_BYTES: usize = 4 << 20;

/// Wall-clock time between two `fdatasync` requests of the file.
pub const SYNC_INTERVAL: Duration = Duration::from_secs(1);

/// How often an idle writer thread looks at the ring (the ring holds 0.16 s of a run).
const IDLE_POLL: Duration = Duration::from_millis(1);

/// Chunk lanes: full-rate data, overview.
const DATA: usize = 0;
const OVERVIEW: usize = 1;

/// Channel ids (each channel's schema has the same id).
const TELEMETRY_CH: u16 = 1;
const TRUTH_CH: u16 = 2;
const OVERVIEW_CH: u16 = 3;

/// Adds the schema of `M` (`ros2msg`) and its channel (`cdr`), both with id `id`.
fn register<M: Message>(w: &mut McapFile<File>, id: u16) {
    w.schema(id, M::SCHEMA_NAME, "ros2msg", M::schema_text().as_bytes());
    w.channel(id, id, M::TOPIC, "cdr");
}

/// Part `index` of the split recording `path`: `<dir>/<stem>_<index, 5 digits>.mcap`
/// (`run.mcap` → `run_00000.mcap`, `run_00001.mcap`, …; rosbag2 names its splits alike).
pub fn part_path(path: &Path, index: u32) -> PathBuf {
    let stem = path
        .file_stem()
        .map_or_else(|| "recording".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!("{stem}_{index:05}.mcap"))
}

/// The file a recording of `path` starts in: `path` itself, or its part 0 when split every
/// `split_ns` ([`RecordOptions::split_ns`]).
pub fn first_file(path: &Path, split_ns: Option<NonZeroU64>) -> PathBuf {
    match split_ns {
        Some(_) => part_path(path, 0),
        None => path.to_owned(),
    }
}

/// The first part of the split recording whose part `part` is ([`part_path`] read backwards:
/// `run_00003.mcap` → `run_00000.mcap`); None for a name that is not a part's.
pub fn first_part_of(part: &Path) -> Option<PathBuf> {
    let name = part.file_name()?.to_str()?;
    let (stem, index) = name.strip_suffix(".mcap")?.rsplit_once('_')?;
    let numbered = index.len() == 5 && index.bytes().all(|b| b.is_ascii_digit());
    numbered.then(|| part_path(&part.with_file_name(format!("{stem}.mcap")), 0))
}

/// What every file of a recording opens with, kept to open the next part of a split one.
struct Opening {
    /// The `run` record.
    run: BTreeMap<String, String>,
    /// The `environment` record.
    environment: BTreeMap<String, String>,
    /// The attachments written before the first message.
    inputs: Vec<Input>,
    epoch_ns: u64,
}

impl Opening {
    /// A new file at `partial` with the opening records, and its sync thread.
    fn write(&self, partial: &Path) -> std::io::Result<(McapFile<File>, Syncer)> {
        let file = create_private(partial)?;
        let syncer = Syncer::start(&file)?;
        let mut w = McapFile::create(file, "ros2", 2, CHUNK_BYTES)?;
        self.records(&mut w)?;
        Ok((w, syncer))
    }

    /// The opening records of the file `w` has just begun: schemas, channels, the `run` and
    /// `environment` records, the attachments; then the first point a failed write goes
    /// back to.
    fn records(&self, w: &mut McapFile<File>) -> std::io::Result<()> {
        register::<TelemetryRecord>(w, TELEMETRY_CH);
        register::<TruthRecord>(w, TRUTH_CH);
        register::<Overview>(w, OVERVIEW_CH);
        w.metadata("run", &self.run)?;
        w.metadata("environment", &self.environment)?;
        for input in &self.inputs {
            w.attachment(&input.name, &input.media_type, self.epoch_ns, &input.data)?;
        }
        w.mark()
    }
}

/// The split of a recording into parts.
struct Split {
    /// The recording's path (parts are named after it).
    path: PathBuf,
    /// Run time each part covers, ns.
    span_ns: u64,
    /// The part being written.
    index: u32,
    /// Run time at which it ends, ns.
    ends_ns: u64,
    /// Ticks seen before it.
    first_tick: u64,
    overwrite: Overwrite,
    opening: Opening,
}

impl Recorder {
    /// Creates the recording of `path` (of its first part, [`part_path`] 0, when split) under
    /// a temporary name beside it (failing now, before any run, if it cannot be written, or if
    /// it exists and may not be replaced), writes
    /// the `run` record (`metadata` and the epoch), the `environment` record and the
    /// attachments, and starts the writer thread.
    pub fn create(
        path: &Path,
        metadata: BTreeMap<String, String>,
        options: RecordOptions,
    ) -> Result<Self, RecordError> {
        let target = first_file(path, options.split_ns);
        let io = |source| RecordError::Io {
            path: target.clone(),
            source,
        };
        check_target(&target, options.overwrite)?;
        let partial = partial_path(&target);
        let mut run = metadata;
        run.insert(EPOCH_KEY.into(), options.epoch_ns.to_string());
        run.insert(EVERY_KEY.into(), options.every.to_string());
        run.insert(TELEMETRY_KEY.into(), TELEMETRY_READING_USED.into());
        if options.split_ns.is_some() {
            run.insert(PART_KEY.into(), "0".into());
        }
        let mut environment = options.environment;
        environment.insert("started".into(), utc_now());
        let opening = Opening {
            run,
            environment,
            inputs: options.inputs,
            epoch_ns: options.epoch_ns,
        };
        let (w, syncer) = opening.write(&partial).map_err(io)?;
        let split = options.split_ns.map(|span| Split {
            path: path.to_owned(),
            span_ns: span.get(),
            index: 0,
            ends_ns: span.get(),
            first_tick: 0,
            overwrite: options.overwrite,
            opening,
        });
        let (ring, consumer) = rtrb::RingBuffer::new(RING_FRAMES);
        let writer_alive = Arc::new(AtomicBool::new(true));
        let written = Arc::new(AtomicU64::new(0));
        let end = Arc::new(Mutex::new(Ending::default()));
        let (alive, count, end_record) = (writer_alive.clone(), written.clone(), end.clone());
        let room = Arc::new(Room::default());
        let made = room.clone();
        let overwrite = options.overwrite;
        let (epoch_ns, every) = (options.epoch_ns, options.every);
        let first = (partial, target.clone());
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || {
                let drain = Drain::new(w, syncer, epoch_ns, every, split, first);
                let (result, partial, target) =
                    drain.run(consumer, &count, &end_record, &made, &alive);
                let result = match result {
                    Ok(n) => publish(&partial, &target, overwrite).map(|()| n),
                    Err(Failure {
                        source,
                        finished: Some(until_s),
                    }) => publish(&partial, &target, overwrite).and_then(|()| {
                        Err(RecordError::WriteFailed {
                            path: target.clone(),
                            kept: Kept::Finished {
                                path: target.clone(),
                                until_s,
                            },
                            source,
                        })
                    }),
                    Err(Failure {
                        source,
                        finished: None,
                    }) => Err(RecordError::WriteFailed {
                        path: target.clone(),
                        kept: Kept::Unfinished {
                            partial: partial.clone(),
                        },
                        source,
                    }),
                };
                alive.store(false, Ordering::Release);
                made.made();
                result
            })
            .map_err(io)?;
        Ok(Recorder {
            ring,
            when_full: options.when_full,
            dropped: 0,
            writer_alive,
            room,
            written,
            end,
            late: Vec::new(),
            thread: Some(thread),
        })
    }

    /// Queues one frame; never allocates. Fails at once if the writer thread has stopped (a
    /// write error, e.g. a full disk): the caller ends the run safely. With
    /// [`WhenFull::Wait`] it waits for room.
    #[inline]
    pub fn push(&mut self, frame: Frame) -> Result<(), RecordError> {
        if !self.writer_alive.load(Ordering::Acquire) {
            return Err(RecordError::WriterGone);
        }
        let mut frame = frame;
        loop {
            match self.ring.push(frame) {
                Ok(()) => return Ok(()),
                Err(rtrb::PushError::Full(f)) => match self.when_full {
                    WhenFull::Drop => {
                        self.dropped += 1;
                        return Ok(());
                    }
                    WhenFull::Wait => {
                        if !self.writer_alive.load(Ordering::Acquire) {
                            return Err(RecordError::WriterGone);
                        }
                        frame = f;
                        let ring = &self.ring;
                        self.room.wait(|| ring.is_full());
                    }
                },
            }
        }
    }

    /// Attaches `input`, a file the run took up while it ran (a controller a `servo ctl load`
    /// swapped in), at `at_ns` of run time: written at [`Recorder::finish`], after the last
    /// frame and before the `end` record that says what it is. Streaming readers meet it
    /// after the frames; [`crate::index::visit_indexed`] finds it first. The caller bounds
    /// how many it attaches (they are held in memory until then).
    pub fn attach(&mut self, input: Input, at_ns: u64) {
        self.late.push((input, at_ns));
    }

    /// Full-rate messages written so far.
    pub fn written(&self) -> u64 {
        self.written.load(Ordering::Relaxed)
    }

    /// Closes the ring, waits for the writer to drain it, writes the `end` metadata record
    /// (how the run ended: reason, tick, …) and the `timing` one, finishes the file, moves it
    /// to its target, and reports the counts or the writer's error.
    pub fn finish(mut self, end: BTreeMap<String, String>) -> Result<RecordStats, RecordError> {
        *self.end.lock().unwrap_or_else(|e| e.into_inner()) = Ending {
            record: end,
            attachments: std::mem::take(&mut self.late),
        };
        let thread = self.thread.take().expect("finish is called once");
        let dropped = self.dropped;
        drop(self); // abandons the ring: the writer drains it and closes the file
        let messages = thread.join().map_err(|_| RecordError::WriterGone)??;
        Ok(RecordStats {
            messages,
            dropped_frames: dropped,
        })
    }
}

/// Why the writer thread's file did not come out whole: the first write error, and the run
/// time (s) up to which the file was finished shorter (None: left unfinished).
struct Failure {
    source: std::io::Error,
    finished: Option<f64>,
}

/// What the writer thread writes after the last frame.
#[derive(Default)]
struct Ending {
    /// The `end` metadata record.
    record: BTreeMap<String, String>,
    /// Attachments written before it, with their run time in ns.
    attachments: Vec<(Input, u64)>,
}

/// The `end` metadata key a recording whose writing failed carries: the write error.
pub const WRITE_FAILED_KEY: &str = "write_failed";

/// The `end` metadata key of a recording cut back after a write failure: the ticks it holds
/// (its `ticks` are the run's).
pub const RECORDED_TICKS_KEY: &str = "recorded_ticks";

/// The `end` reason of a part of a split recording that is not the last
/// ([`RecordOptions::split_ns`]).
pub const SPLIT_REASON: &str = "split";

/// The `run` and `end` metadata key of a split recording's part: its index, from 0.
pub const PART_KEY: &str = "part";

/// The `end` metadata key of a split recording's part: the run's ticks before its first
/// frame (its first tick's index).
pub const FIRST_TICK_KEY: &str = "part_first_tick";

/// The `end` metadata key of a split recording's part: the ticks it holds (recorded or
/// decimated away).
pub const PART_TICKS_KEY: &str = "part_ticks";

/// The `end` metadata key of a split recording's part that is not the last: the next part's
/// file name.
pub const NEXT_PART_KEY: &str = "next_part";

/// A path's file name, for a record.
fn file_name(path: &Path) -> String {
    path.file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
}

impl Split {
    /// What a part's `end` record says about it when the run has seen `ticks`.
    fn part_record(&self, ticks: u64) -> [(String, String); 3] {
        [
            (PART_KEY.into(), self.index.to_string()),
            (FIRST_TICK_KEY.into(), self.first_tick.to_string()),
            (PART_TICKS_KEY.into(), (ticks - self.first_tick).to_string()),
        ]
    }
}

/// The `run` metadata key holding the log-time epoch (ns since the Unix epoch).
pub const EPOCH_KEY: &str = "log_time_epoch_ns";

/// The `run` metadata key holding the full-rate decimation ([`RecordOptions::every`]).
pub const EVERY_KEY: &str = "record_every";

/// Key of the `run` metadata naming the telemetry convention of the recording's frames:
/// [`TELEMETRY_READING_USED`] since contract v6; absent in older recordings, whose telemetry
/// paired each tick's reference with the next reading.
pub const TELEMETRY_KEY: &str = "telemetry";

/// The contract-v6 telemetry: each tick's reference with the reading it acted on.
pub const TELEMETRY_READING_USED: &str =
    "reference with the reading the tick acted on (contract v6)";

/// Now, as an RFC 3339 UTC time.
fn utc_now() -> String {
    humantime::format_rfc3339_millis(SystemTime::now()).to_string()
}

/// The writer thread's state.
struct Drain {
    w: McapFile<File>,
    /// The sync thread of the file being written.
    syncer: Syncer,
    /// The file being written, under its temporary name, and where it goes when finished.
    partial: PathBuf,
    target: PathBuf,
    /// The split into parts, if asked.
    split: Option<Split>,
    epoch_ns: u64,
    every: u32,
    /// Ticks seen, recorded or not.
    ticks: u64,
    overview: OverviewBin,
    sequence: u32,
    overview_sequence: u32,
    written: u64,
    started: Instant,
    synced: Instant,
}

impl Drain {
    fn new(
        w: McapFile<File>,
        syncer: Syncer,
        epoch_ns: u64,
        every: NonZeroU32,
        split: Option<Split>,
        (partial, target): (PathBuf, PathBuf),
    ) -> Self {
        Drain {
            w,
            syncer,
            partial,
            target,
            split,
            epoch_ns,
            every: every.get(),
            ticks: 0,
            overview: OverviewBin::default(),
            sequence: 0,
            overview_sequence: 0,
            written: 0,
            started: Instant::now(),
            synced: Instant::now(),
        }
    }

    /// Encodes and writes until the producer is gone and the ring is empty, then writes the
    /// `end` and `timing` records and the summary. A failed write (a full disk, a file size
    /// limit, a quota) stops the frames (`alive` goes false: the producer ends the run at its
    /// next push; what it pushed meanwhile is dropped) and the file is finished with the part
    /// that fit: cut back to the last chunk written, and to earlier ones while its end records
    /// still do not fit ([`McapFile::rewind`]).
    fn run(
        mut self,
        ring: rtrb::Consumer<Frame>,
        count: &AtomicU64,
        end: &Mutex<Ending>,
        room: &Room,
        alive: &AtomicBool,
    ) -> (Result<u64, Failure>, PathBuf, PathBuf) {
        let drained = self.drain(ring, count, end, room, alive);
        let result = match (drained, self.syncer.stop()) {
            (Ok(n), Ok(())) => Ok(n),
            (Ok(_), Err(source)) => Err(Failure {
                source,
                finished: None,
            }),
            (Err(failure), _) => Err(failure),
        };
        (result, self.partial, self.target)
    }

    /// [`Drain::run`]'s work but the last sync, on the part being written.
    fn drain(
        &mut self,
        mut ring: rtrb::Consumer<Frame>,
        count: &AtomicU64,
        end: &Mutex<Ending>,
        room: &Room,
        alive: &AtomicBool,
    ) -> Result<u64, Failure> {
        let mut failed = self.frames(&mut ring, count, room).err();
        if failed.is_some() {
            alive.store(false, Ordering::Release);
            while !(ring.is_abandoned() && ring.is_empty()) {
                let n = ring.slots();
                if let Ok(c) = ring.read_chunk(n) {
                    c.commit_all();
                }
                room.made();
                std::thread::sleep(IDLE_POLL);
            }
        } else if let Some((t, o)) = self.overview.take() {
            self.overview_message(t, &o);
        }
        let mut end = std::mem::take(&mut *end.lock().unwrap_or_else(|e| e.into_inner()));
        if let Some(s) = &self.split {
            end.record.extend(s.part_record(self.ticks));
        }
        if let Some(e) = &failed {
            end.record.insert(WRITE_FAILED_KEY.into(), e.to_string());
            let _ = self.w.rewind();
        }
        loop {
            if failed.is_some() {
                // What the file holds now, beside what the run did.
                let kept = self.w.messages_on(TELEMETRY_CH);
                end.record
                    .insert(RECORDED_TICKS_KEY.into(), kept.to_string());
            }
            match self.finish(&end) {
                Ok(()) => break,
                Err(e) => {
                    if failed.is_none() {
                        end.record.insert(WRITE_FAILED_KEY.into(), e.to_string());
                    }
                    failed.get_or_insert(e);
                    if !matches!(self.w.rewind(), Ok(true)) {
                        return Err(Failure {
                            source: failed.expect("set above"),
                            finished: None,
                        });
                    }
                }
            }
        }
        match failed {
            None => Ok(self.written),
            Some(source) => Err(Failure {
                source,
                finished: Some(self.w.end_ns().saturating_sub(self.epoch_ns) as f64 * 1e-9),
            }),
        }
    }

    /// Encodes and writes the frames until the producer is gone and the ring is empty.
    fn frames(
        &mut self,
        ring: &mut rtrb::Consumer<Frame>,
        count: &AtomicU64,
        room: &Room,
    ) -> std::io::Result<()> {
        loop {
            let available = ring.slots();
            if available == 0 {
                if ring.is_abandoned() && ring.is_empty() {
                    return Ok(());
                }
                std::thread::sleep(IDLE_POLL);
                continue;
            }
            // In batches, so that a waiting producer gets room while the rest is encoded.
            let chunk = ring
                .read_chunk(available.min(RING_FRAMES / 8))
                .expect("slots are available");
            for frame in chunk.into_iter() {
                self.frame(&frame)?;
            }
            room.made();
            count.store(self.written, Ordering::Relaxed);
            if self.synced.elapsed() >= SYNC_INTERVAL {
                self.syncer.request()?;
                self.synced = Instant::now();
            }
        }
    }

    /// Finishes the part being written (its `end` record says it is one, and which ticks it
    /// holds), moves it into place and goes on in the next, on the same compressors and
    /// buffers. Whatever fails leaves a file being written that the run's end finishes as any
    /// failed write ([`Drain::run`]): the part, when the next could not be created or the part
    /// not finished; the next one, once the part is closed (a part that could not be synced
    /// or moved into place is left under its temporary name, whole).
    fn next_part(&mut self) -> std::io::Result<()> {
        let split = self.split.as_ref().expect("called on a split recording");
        let next = part_path(&split.path, split.index + 1);
        check_target(&next, split.overwrite).map_err(std::io::Error::other)?;
        let mut record = BTreeMap::from(split.part_record(self.ticks));
        record.insert("reason".into(), SPLIT_REASON.into());
        record.insert(NEXT_PART_KEY.into(), file_name(&next));
        let next_partial = partial_path(&next);
        let file = create_private(&next_partial)?;
        let syncer = match Syncer::start(&file) {
            Ok(s) => s,
            Err(e) => {
                let _ = std::fs::remove_file(&next_partial);
                return Err(e);
            }
        };
        let ending = Ending {
            record,
            attachments: Vec::new(),
        };
        if let Err(e) = self.finish(&ending) {
            let _ = syncer.stop();
            let _ = std::fs::remove_file(&next_partial);
            return Err(e);
        }
        // The part is closed: from here on the run goes on in the next file.
        let old_syncer = std::mem::replace(&mut self.syncer, syncer);
        let done = std::mem::replace(&mut self.partial, next_partial);
        let done_target = std::mem::replace(&mut self.target, next);
        let split = self.split.as_mut().expect("called on a split recording");
        split.index += 1;
        split.ends_ns = split.ends_ns.saturating_add(split.span_ns);
        split.first_tick = self.ticks;
        split
            .opening
            .run
            .insert(PART_KEY.into(), split.index.to_string());
        self.started = Instant::now();
        let opened = self
            .w
            .next_file(file, "ros2")
            .and_then(|_closed| split.opening.records(&mut self.w));
        let synced = old_syncer.stop();
        let published =
            publish(&done, &done_target, split.overwrite).map_err(std::io::Error::other);
        opened.and(synced).and(published)
    }

    /// Closes the open chunks and writes the attachments taken up during the run, the `end`
    /// and `timing` records and the summary.
    fn finish(&mut self, end: &Ending) -> std::io::Result<()> {
        self.w.close_chunk(DATA)?;
        self.w.close_chunk(OVERVIEW)?;
        for (input, at_ns) in &end.attachments {
            let log_ns = self.epoch_ns.saturating_add(*at_ns);
            self.w
                .attachment(&input.name, &input.media_type, log_ns, &input.data)?;
        }
        self.w.metadata("end", &end.record)?;
        let timing = BTreeMap::from([
            ("finished".to_string(), utc_now()),
            (
                "wall_s".to_string(),
                format!("{:.3}", self.started.elapsed().as_secs_f64()),
            ),
        ]);
        self.w.metadata("timing", &timing)?;
        self.w.close()
    }

    /// One tick: its two messages (unless decimated away), its share of the overview; closes
    /// chunks that are full.
    #[inline]
    fn frame(&mut self, frame: &Frame) -> std::io::Result<()> {
        if self
            .split
            .as_ref()
            .is_some_and(|s| frame.time_ns >= s.ends_ns)
        {
            self.next_part()?;
        }
        if self.ticks.is_multiple_of(u64::from(self.every)) {
            self.full_rate(frame)?;
        }
        self.ticks += 1;
        if let Some((period_start, o)) = self.overview.add(frame) {
            let start = self.epoch_ns + period_start;
            if self
                .w
                .chunk_start(OVERVIEW)
                .is_some_and(|first| start - first >= OVERVIEW_CHUNK_SPAN_NS)
            {
                self.w.close_chunk(OVERVIEW)?;
            }
            self.overview_message(period_start, &o);
        }
        Ok(())
    }

    /// The tick's `/telemetry` and `/truth` messages.
    #[inline]
    fn full_rate(&mut self, frame: &Frame) -> std::io::Result<()> {
        let t = self.epoch_ns + frame.time_ns;
        if self
            .w
            .chunk_start(DATA)
            .is_some_and(|start| t - start >= CHUNK_SPAN_NS)
        {
            self.w.close_chunk(DATA)?;
        }
        let seq = self.sequence;
        self.w
            .message(DATA, TELEMETRY_CH, seq, t, |b| frame.telemetry.encode(b));
        let bytes = self
            .w
            .message(DATA, TRUTH_CH, seq, t, |b| frame.truth.encode(b));
        self.sequence = seq.wrapping_add(1);
        self.written += 2;
        if bytes >= CHUNK_BYTES {
            self.w.close_chunk(DATA)?;
        }
        Ok(())
    }

    fn overview_message(&mut self, period_start_ns: u64, o: &Overview) {
        let t = self.epoch_ns + period_start_ns;
        let seq = self.overview_sequence;
        self.w
            .message(OVERVIEW, OVERVIEW_CH, seq, t, |b| o.encode(b));
        self.overview_sequence = seq.wrapping_add(1);
    }
}
