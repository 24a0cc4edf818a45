//! MCAP writing off the servo tick: the loop pushes [`Frame`]s into a preallocated wait-free
//! ring; a writer thread encodes them and writes zstd-compressed chunks. Log time is the
//! simulation time, so a seeded run gives a byte-identical file.
//!
//! Compression choice (measured, `cargo bench --bench recorder`): the mcap crate feeds every
//! message record to the compressor separately; LZ4's frame API pays a checksum and a bound
//! computation per write (≈ 3–4× real time), zstd level 1 in the writer thread ≈ 5×. zstd's
//! own worker threads are off: on two cores they compete with the servo loop.

use crate::frame::{Frame, Telemetry, Truth};
use mcap::records::{MessageHeader, Metadata};
use mcap::{Compression, WriteOptions, Writer};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
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
    /// The writer thread stopped early (its error is reported by [`Recorder::finish`]).
    #[error("the recorder thread stopped")]
    WriterGone,
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
    /// Creates `path` (failing now, before any run, if it cannot be written), writes the
    /// metadata record `run` with `metadata`, and starts the writer thread. zstd chunks.
    pub fn create(
        path: &Path,
        metadata: BTreeMap<String, String>,
        when_full: WhenFull,
    ) -> Result<Self, RecordError> {
        Self::create_with(path, metadata, when_full, Chunks::Zstd)
    }

    /// [`Recorder::create`] with the chunk storage chosen.
    pub fn create_with(
        path: &Path,
        metadata: BTreeMap<String, String>,
        when_full: WhenFull,
        chunks: Chunks,
    ) -> Result<Self, RecordError> {
        let io = |source| RecordError::Io {
            path: path.to_owned(),
            source,
        };
        let mc = |source| RecordError::Mcap {
            path: path.to_owned(),
            source,
        };
        let file = File::create(path).map_err(io)?;
        let options = WriteOptions::new()
            .compression(match chunks {
                Chunks::Zstd => Some(Compression::Zstd),
                Chunks::Raw => None,
            })
            .compression_level(1)
            .compression_threads(0)
            .chunk_size(Some(4 << 20))
            .profile("")
            .library("fts-servo recorder")
            // Chunk indexes stay (readers seek by chunk); per-message indexes are optional in
            // the spec and cost a quarter of the write time.
            .emit_message_indexes(false);
        let mut w = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(mc)?;
        let channels = add_channels(&mut w).map_err(mc)?;
        w.write_metadata(&Metadata {
            name: "run".into(),
            metadata,
        })
        .map_err(mc)?;
        let (ring, consumer) = rtrb::RingBuffer::new(RING_FRAMES);
        let writer_alive = Arc::new(AtomicBool::new(true));
        let written = Arc::new(AtomicU64::new(0));
        let (alive, count, owned_path) = (writer_alive.clone(), written.clone(), path.to_owned());
        let thread = std::thread::Builder::new()
            .name("mcap-writer".into())
            .spawn(move || {
                let result =
                    drain(consumer, w, channels, &count).map_err(|source| RecordError::Mcap {
                        path: owned_path,
                        source,
                    });
                alive.store(false, Ordering::Release);
                result
            })
            .map_err(io)?;
        Ok(Recorder {
            ring,
            when_full,
            dropped: 0,
            writer_alive,
            written,
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

    /// Closes the ring, waits for the writer to finish the file, and reports the counts or
    /// the writer's error.
    pub fn finish(mut self) -> Result<RecordStats, RecordError> {
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
    w.finish()?;
    Ok(written)
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
