//! MCAP writing off the servo tick: the loop pushes [`Frame`]s into a preallocated wait-free
//! ring; a writer thread encodes them and writes zstd-compressed chunks with message indexes
//! (profile `ros2`: what Foxglove's indexed reader expects). Log time is the simulation time,
//! so a seeded run gives a byte-identical file.
//!
//! The file is written under a temporary name beside the target (`<name>.<pid>.partial`) and
//! renamed when finished; an existing target is kept unless [`Overwrite::Replace`] is asked
//! for. A run that dies leaves the `.partial` file, which the reader recovers up to its last
//! complete chunk (4 MiB of records, ≈ 26 ms of a 199.6 kHz run).
//!
//! Compression choice (measured, `cargo bench --bench recorder`): the mcap crate feeds every
//! message record to the compressor separately; LZ4's frame API pays a checksum and a bound
//! computation per write (≈ 3–4× real time), zstd level 1 in the writer thread ≈ 5×. zstd's
//! own worker threads are off: on two cores they compete with the servo loop.

use crate::frame::{Frame, Telemetry, Truth};
use mcap::records::{MessageHeader, Metadata};
use mcap::{Attachment, Compression, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

/// Recording errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// The output file could not be created or written.
    #[error("cannot write {path}: {source}")]
    Io {
        /// Output path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The MCAP layer failed (usually an I/O error underneath, e.g. a full disk).
    #[error("writing {path}: {source}")]
    Mcap {
        /// Output path.
        path: PathBuf,
        /// Cause.
        source: mcap::McapError,
    },
    /// The target exists and [`Overwrite::Refuse`] was asked for.
    #[error("{} exists: not overwritten (pass --overwrite to replace it)", path.display())]
    Exists {
        /// The target.
        path: PathBuf,
    },
    /// The writer thread stopped early (its error is reported by [`Recorder::finish`]).
    #[error("the recorder thread stopped")]
    WriterGone,
}

/// Whether an existing file at the target may be replaced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overwrite {
    /// Keep it: creating the recording fails with [`RecordError::Exists`].
    Refuse,
    /// Replace it when the new recording is finished.
    Replace,
}

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
    /// Chunk storage.
    pub chunks: Chunks,
    /// Existing target.
    pub overwrite: Overwrite,
    /// Files embedded as attachments, before the first message.
    pub inputs: Vec<Input>,
}

impl Default for RecordOptions {
    /// Wait when full, zstd chunks, never overwrite, nothing attached.
    fn default() -> Self {
        RecordOptions {
            when_full: WhenFull::Wait,
            chunks: Chunks::Zstd,
            overwrite: Overwrite::Refuse,
            inputs: Vec::new(),
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
    /// Messages written (two per recorded frame).
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
    written: Arc<AtomicU64>,
    /// The `end` metadata record, handed to the writer thread at [`Recorder::finish`].
    end: Arc<Mutex<BTreeMap<String, String>>>,
    thread: Option<JoinHandle<Result<u64, RecordError>>>,
}

/// Frames the ring holds (≈ 0.1 s at 199.6 kHz; 20 k × 136 B ≈ 2.7 MB).
pub const RING_FRAMES: usize = 1 << 15;

/// How chunks are stored.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Chunks {
    /// zstd level 1 (≈ 6× smaller; 0.2–0.3 s of one core per simulated second at 199.6 kHz).
    Zstd,
    /// Uncompressed (≈ 25 MB per simulated second; ≈ 10× cheaper to write): for a recorder
    /// that shares the cores with a real-time loop.
    Raw,
}

impl Recorder {
    /// Creates the recording of `path` under a temporary name beside it (failing now, before
    /// any run, if it cannot be written, or if `path` exists and may not be replaced), writes
    /// the metadata record `run` with `metadata` and the attachments, and starts the writer
    /// thread.
    pub fn create(
        path: &Path,
        metadata: BTreeMap<String, String>,
        options: RecordOptions,
    ) -> Result<Self, RecordError> {
        let io = |source| RecordError::Io {
            path: path.to_owned(),
            source,
        };
        let mc = |source| RecordError::Mcap {
            path: path.to_owned(),
            source,
        };
        check_target(path, options.overwrite)?;
        let partial = partial_path(path);
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&partial)
            .map_err(io)?;
        let mut w = WriteOptions::new()
            .compression(match options.chunks {
                Chunks::Zstd => Some(Compression::Zstd),
                Chunks::Raw => None,
            })
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(CHUNK_BYTES))
            .profile("ros2")
            .library("fts-servo recorder")
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(mc)?;
        let channels = add_channels(&mut w).map_err(mc)?;
        w.write_metadata(&Metadata {
            name: "run".into(),
            metadata,
        })
        .map_err(mc)?;
        for input in &options.inputs {
            w.attach(&Attachment {
                log_time: 0,
                create_time: 0,
                name: input.name.clone(),
                media_type: input.media_type.clone(),
                data: std::borrow::Cow::Borrowed(&input.data),
            })
            .map_err(mc)?;
        }
        let (ring, consumer) = rtrb::RingBuffer::new(RING_FRAMES);
        let writer_alive = Arc::new(AtomicBool::new(true));
        let written = Arc::new(AtomicU64::new(0));
        let end = Arc::new(Mutex::new(BTreeMap::new()));
        let (alive, count, end_record) = (writer_alive.clone(), written.clone(), end.clone());
        let (target, overwrite) = (path.to_owned(), options.overwrite);
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || {
                let result = drain(consumer, w, channels, &count, &end_record)
                    .map_err(|source| RecordError::Mcap {
                        path: target.clone(),
                        source,
                    })
                    .and_then(|n| publish(&partial, &target, overwrite).map(|()| n));
                alive.store(false, Ordering::Release);
                result
            })
            .map_err(io)?;
        Ok(Recorder {
            ring,
            when_full: options.when_full,
            dropped: 0,
            writer_alive,
            written,
            end,
            thread: Some(thread),
        })
    }

    /// Queues one frame; never allocates. With [`WhenFull::Wait`] it spins until there is room
    /// and fails only if the writer thread has died (e.g. disk full).
    #[inline]
    pub fn push(&mut self, frame: Frame) -> Result<(), RecordError> {
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
                        std::hint::spin_loop();
                        std::thread::yield_now();
                    }
                },
            }
        }
    }

    /// Messages written so far.
    pub fn written(&self) -> u64 {
        self.written.load(Ordering::Relaxed)
    }

    /// Closes the ring, waits for the writer to drain it, writes the `end` metadata record
    /// (how the run ended: reason, tick, …), finishes the file, moves it to its target, and
    /// reports the counts or the writer's error.
    pub fn finish(mut self, end: BTreeMap<String, String>) -> Result<RecordStats, RecordError> {
        *self.end.lock().unwrap_or_else(|e| e.into_inner()) = end;
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

struct Channels {
    telemetry: u16,
    truth: u16,
}

fn add_channels<W: std::io::Write + std::io::Seek>(
    w: &mut Writer<W>,
) -> mcap::McapResult<Channels> {
    let no_meta = BTreeMap::new();
    let ts = w.add_schema(
        Telemetry::SCHEMA_NAME,
        "ros2msg",
        Telemetry::schema_text().as_bytes(),
    )?;
    let rs = w.add_schema(
        Truth::SCHEMA_NAME,
        "ros2msg",
        Truth::schema_text().as_bytes(),
    )?;
    Ok(Channels {
        telemetry: w.add_channel(ts, Telemetry::TOPIC, "cdr", &no_meta)?,
        truth: w.add_channel(rs, Truth::TOPIC, "cdr", &no_meta)?,
    })
}

/// The writer thread: encodes and writes until the producer is gone and the ring is empty.
fn drain<W: std::io::Write + std::io::Seek>(
    mut ring: rtrb::Consumer<Frame>,
    mut w: Writer<W>,
    ch: Channels,
    count: &AtomicU64,
    end: &Mutex<BTreeMap<String, String>>,
) -> mcap::McapResult<u64> {
    let mut buf = Vec::with_capacity(256);
    let mut sequence = 0u32;
    let mut written = 0u64;
    loop {
        let available = ring.slots();
        if available == 0 {
            if ring.is_abandoned() && ring.is_empty() {
                break;
            }
            std::thread::yield_now();
            continue;
        }
        let chunk = ring.read_chunk(available).expect("slots are available");
        for frame in chunk.into_iter() {
            let time_ns = frame.time_ns;
            for (channel_id, encode) in [
                (ch.telemetry, &frame.telemetry as &dyn Encode),
                (ch.truth, &frame.truth as &dyn Encode),
            ] {
                buf.clear();
                encode.encode_into(&mut buf);
                let header = MessageHeader {
                    channel_id,
                    sequence,
                    log_time: time_ns,
                    publish_time: time_ns,
                };
                w.write_to_known_channel(&header, &buf)?;
                written += 1;
            }
            sequence = sequence.wrapping_add(1);
        }
        count.store(written, Ordering::Relaxed);
    }
    let end = std::mem::take(&mut *end.lock().unwrap_or_else(|e| e.into_inner()));
    w.write_metadata(&Metadata {
        name: "end".into(),
        metadata: end,
    })?;
    w.finish()?;
    Ok(written)
}

/// Target bytes of records per chunk (4 MiB ≈ 26 ms of a 199.6 kHz run: what a killed run
/// loses at most).
pub const CHUNK_BYTES: u64 = 4 << 20;

/// Whether a recording may be written to `path`: a device, a directory or a link is never
/// replaced; an existing file only with [`Overwrite::Replace`]. [`Recorder::create`] checks
/// this; a caller that starts other work first (the HIL processes) can check it earlier.
pub fn check_target(path: &Path, overwrite: Overwrite) -> Result<(), RecordError> {
    let Ok(existing) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    if !existing.is_file() {
        return Err(RecordError::Io {
            path: path.to_owned(),
            source: std::io::Error::other("exists and is not a regular file"),
        });
    }
    if overwrite == Overwrite::Refuse {
        return Err(RecordError::Exists {
            path: path.to_owned(),
        });
    }
    Ok(())
}

/// `<dir>/<name>.<pid>.partial`: the recording while it is written.
pub fn partial_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "recording".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!("{name}.{}.partial", std::process::id()))
}

/// Moves the finished `partial` file to `target`: without replacing an existing one (a hard
/// link fails if `target` exists, atomically) unless `overwrite` is `Replace`.
fn publish(partial: &Path, target: &Path, overwrite: Overwrite) -> Result<(), RecordError> {
    let io = |source| RecordError::Io {
        path: target.to_owned(),
        source,
    };
    match overwrite {
        Overwrite::Replace => std::fs::rename(partial, target).map_err(io),
        Overwrite::Refuse => match std::fs::hard_link(partial, target) {
            Ok(()) => std::fs::remove_file(partial).map_err(io),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(RecordError::Exists {
                path: target.to_owned(),
            }),
            // Filesystems without hard links: check, then rename.
            Err(_) if !target.exists() => std::fs::rename(partial, target).map_err(io),
            Err(e) => Err(io(e)),
        },
    }
}

/// Object-safe encoding of the two record types.
trait Encode {
    fn encode_into(&self, out: &mut Vec<u8>);
}

impl Encode for Telemetry {
    fn encode_into(&self, out: &mut Vec<u8>) {
        self.encode(out)
    }
}

impl Encode for Truth {
    fn encode_into(&self, out: &mut Vec<u8>) {
        self.encode(out)
    }
}
