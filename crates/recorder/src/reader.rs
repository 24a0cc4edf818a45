//! Reading a recording back as a stream: one record (at most one chunk) in memory at a time,
//! whatever the file's length; chunk and attachment CRCs checked; a corrupt chunk reported with
//! its offset and skipped (the records around it are still read); an unfinished file (a run
//! that was killed, a full disk) read up to its last complete record. The records are parsed
//! here, following the MCAP specification, so every one of those cases is in our hands; the
//! official `mcap` crate reads the same files in the tests.

use crate::fields::Fields;
use crate::frame::{Frame, Message, TelemetryRecord, TruthRecord};
use crate::mcap_format::{op, MAGIC};
use crate::overview::Overview;
use crate::verify::{ChunkIndex, Counts, Ledger};
use crate::writer::EPOCH_KEY;
use std::collections::BTreeMap;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// Reading errors: the file cannot be opened, or it is not a recording at all.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Not an MCAP file (no MCAP magic at its start).
    #[error("{path} is not an MCAP recording (no MCAP magic at its start)")]
    NotMcap {
        /// File.
        path: PathBuf,
    },
    /// A finished file whose summary or an indexed record fails its check.
    #[error("{path} is damaged: {reason}")]
    Damaged {
        /// File.
        path: PathBuf,
        /// What is wrong, and where.
        reason: String,
    },
}

/// What a reader is shown, in file order: the `run` metadata and the attachments before the
/// first frame, the `end` metadata after the last.
pub trait Visit {
    /// A metadata record.
    fn metadata(&mut self, _name: &str, _values: &BTreeMap<String, String>) {}
    /// An attachment (an input file of the run).
    fn attachment(&mut self, _name: &str, _data: &[u8]) {}
    /// One tick: telemetry and truth, its time in ns from the run's start.
    fn frame(&mut self, _frame: &Frame) {}
    /// Every message of every channel as written, its time in ns from the run's start (its log
    /// time less the `run` record's epoch).
    fn message(&mut self, _topic: &str, _sequence: u32, _time_ns: u64, _data: &[u8]) {}
}

/// How far a file could be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FileState {
    /// Complete, with its summary and footer.
    Finished,
    /// It ends early (the run was killed or the disk filled): everything up to the last
    /// complete record was read.
    Unfinished,
    /// The record structure breaks at `at_byte` (an impossible record length): what came
    /// before was read, nothing after can be found.
    Corrupt {
        /// Offset of the record that cannot be right.
        at_byte: u64,
        /// What is wrong with it.
        reason: String,
    },
}

/// A record that failed its check (a chunk that fails is skipped whole; a failed index,
/// summary or CRC check skips nothing but makes the file untrustworthy).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadRecord {
    /// Offset of the record in the file.
    pub at_byte: u64,
    /// What failed (CRC, size, compression).
    pub reason: String,
}

/// What a read found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadReport {
    /// Full-rate messages read (`/telemetry` and `/truth`).
    pub messages: u64,
    /// Frames (tick pairs of telemetry and truth) read.
    pub frames: u64,
    /// Time of the last frame from the run's start, ns.
    pub last_time_ns: Option<u64>,
    /// Whether the file was complete.
    pub state: FileState,
    /// Records that failed their check and were skipped (the first [`MAX_BAD_LISTED`]).
    pub bad: Vec<BadRecord>,
    /// How many records failed their check in all.
    pub bad_count: u64,
}

/// Bad records listed in a [`ReadReport`] (the rest are counted).
pub const MAX_BAD_LISTED: usize = 16;

impl ReadReport {
    /// Whether anything in the file failed its check.
    pub fn is_damaged(&self) -> bool {
        self.bad_count > 0 || matches!(self.state, FileState::Corrupt { .. })
    }

    /// Whether the file is complete and every check passed: what a reader may trust without
    /// being told to salvage.
    pub fn is_intact(&self) -> bool {
        self.state == FileState::Finished && !self.is_damaged()
    }
}

impl std::fmt::Display for ReadReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let until = self.last_time_ns.map_or("nothing".to_string(), |t| {
            format!("t = {:.6} s", t as f64 * 1e-9)
        });
        match &self.state {
            FileState::Finished => write!(f, "complete, {} messages", self.messages)?,
            FileState::Unfinished => write!(
                f,
                "unfinished, {} messages recovered up to {until}",
                self.messages
            )?,
            FileState::Corrupt { at_byte, reason } => write!(
                f,
                "unreadable from byte {at_byte} ({reason}); {} messages read up to {until}",
                self.messages
            )?,
        }
        if let Some(first) = self.bad.first() {
            write!(
                f,
                "; damaged: {} failed check(s), the first at byte {} ({})",
                self.bad_count, first.at_byte, first.reason
            )?;
        }
        Ok(())
    }
}

/// Largest record accepted, bytes (attachments are input files, bounded at 64 MiB).
pub const MAX_RECORD_BYTES: u64 = 256 << 20;

/// Largest decompressed chunk accepted, bytes.
pub const MAX_CHUNK_BYTES: u64 = 64 << 20;

/// Streams `path` into `visit`. Errors only when the file cannot be opened or is not MCAP; a
/// truncated or corrupt file is read as far as it is intact and says so in the report.
pub fn stream(path: &Path, visit: &mut impl Visit) -> Result<ReadReport, ReadError> {
    let io = |source| ReadError::Io {
        path: path.to_owned(),
        source,
    };
    let (file, _) = daq_io::input_file::open_regular(path, u64::MAX).map_err(io)?;
    let mut input = BufReader::with_capacity(1 << 20, file);
    let mut magic = [0u8; 8];
    if read_full(&mut input, &mut magic).map_err(io)? < 8 || &magic != MAGIC {
        return Err(ReadError::NotMcap {
            path: path.to_owned(),
        });
    }
    let mut s = Streamer::default();
    let mut ledger = Ledger::default();
    let mut data_crc = crc32fast::Hasher::new();
    data_crc.update(MAGIC);
    let mut at = 8u64;
    let mut head = [0u8; 9];
    let mut body = Vec::new();
    let state = loop {
        if read_full(&mut input, &mut head).map_err(io)? < 9 {
            break FileState::Unfinished;
        }
        let opcode = head[0];
        let len = u64::from_le_bytes(head[1..].try_into().expect("8 bytes"));
        if len > MAX_RECORD_BYTES {
            break FileState::Corrupt {
                at_byte: at,
                reason: format!("record length {len} exceeds {MAX_RECORD_BYTES}"),
            };
        }
        body.clear();
        let got = (&mut input).take(len).read_to_end(&mut body).map_err(io)?;
        if (got as u64) < len {
            break FileState::Unfinished;
        }
        if ledger.in_summary() {
            let counts = Counts {
                per_channel: &s.per_channel,
                time_range: s.time_range,
            };
            if opcode == op::FOOTER {
                if let Err(reason) = ledger.footer(at, &head, &body) {
                    s.bad(at, reason);
                }
                let mut tail = [0u8; 9];
                let n = read_full(&mut input, &mut tail).map_err(io)?;
                if n < 8 || tail[..8] != MAGIC[..] {
                    s.bad(
                        at + 9 + len,
                        "the closing magic is missing or damaged".into(),
                    );
                } else if n > 8 {
                    s.bad(at + 9 + len + 8, "bytes after the closing magic".into());
                }
                break FileState::Finished;
            }
            if let Err(reason) = ledger.summary_record(at, &head, &body, &counts) {
                s.bad(at, reason);
            }
        } else if opcode == op::DATA_END {
            if let Err(reason) =
                ledger.data_end(at, &body, data_crc.clone().finalize(), s.bad_count > 0)
            {
                s.bad(at, reason);
            }
        } else {
            data_crc.update(&head);
            data_crc.update(&body);
            let decoded = s.record(opcode, &body, visit);
            let index = (opcode == op::CHUNK && decoded.is_ok())
                .then(|| std::mem::take(&mut s.chunk_index));
            if let Err(reason) = decoded {
                s.bad(at, reason);
            }
            if let Err(reason) = ledger.data_record(at, opcode, &body, index) {
                s.bad(at, reason);
            }
        }
        at += 9 + len;
    };
    Ok(ReadReport {
        messages: s.messages,
        frames: s.frames,
        last_time_ns: s.last_time_ns,
        state,
        bad: s.bad,
        bad_count: s.bad_count,
    })
}

/// Reads until `buf` is full or the file ends; the bytes read.
fn read_full(input: &mut impl Read, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match input.read(&mut buf[n..]) {
            Ok(0) => break,
            Ok(k) => n += k,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(n)
}

/// Pairs the messages of a tick into frames.
#[derive(Default)]
pub(crate) struct Streamer {
    topics: BTreeMap<u16, String>,
    epoch_ns: u64,
    pending: Option<(u32, u64, TelemetryRecord)>,
    messages: u64,
    frames: u64,
    last_time_ns: Option<u64>,
    bad: Vec<BadRecord>,
    bad_count: u64,
    zstd: Option<zstd::bulk::Decompressor<'static>>,
    chunk: Vec<u8>,
    /// Messages per channel id, of every channel.
    per_channel: BTreeMap<u16, u64>,
    /// Earliest and latest log time of any message.
    time_range: Option<(u64, u64)>,
    /// Each message of the chunk being decoded: per channel, log time and offset in the
    /// chunk's records (what its message indexes must say).
    chunk_index: ChunkIndex,
}

impl Streamer {
    fn bad(&mut self, at_byte: u64, reason: String) {
        self.bad_count += 1;
        if self.bad.len() < MAX_BAD_LISTED {
            self.bad.push(BadRecord { at_byte, reason });
        }
    }

    /// One record of the data section.
    pub(crate) fn record(
        &mut self,
        opcode: u8,
        body: &[u8],
        visit: &mut impl Visit,
    ) -> Result<(), String> {
        let mut f = Fields(body);
        match opcode {
            op::CHANNEL => {
                let id = f.u16()?;
                let _schema = f.u16()?;
                self.topics.insert(id, f.str()?);
            }
            op::METADATA => {
                let name = f.str()?;
                let values = f.string_map()?;
                if name == "run" {
                    self.epoch_ns = values
                        .get(EPOCH_KEY)
                        .and_then(|e| e.parse().ok())
                        .unwrap_or(0);
                }
                visit.metadata(&name, &values);
            }
            op::ATTACHMENT => {
                let checked = body.len().checked_sub(4).ok_or("record too short")?;
                let crc = u32::from_le_bytes(body[checked..].try_into().expect("4"));
                if crc != 0 && crc != crc32fast::hash(&body[..checked]) {
                    return Err("attachment CRC mismatch".into());
                }
                let (_log, _create) = (f.u64()?, f.u64()?);
                let name = f.str()?;
                let _media = f.str()?;
                let n = f.u64()?;
                let data = f.bytes(usize::try_from(n).map_err(|_| "attachment too large")?)?;
                visit.attachment(&name, data);
            }
            op::MESSAGE => self.message(body, visit)?,
            op::CHUNK => self.chunk(body, visit)?,
            _ => {}
        }
        Ok(())
    }

    /// A chunk: size, compression and CRC checked before any of its records is shown (a
    /// corrupt chunk yields nothing, never garbage).
    fn chunk(&mut self, body: &[u8], visit: &mut impl Visit) -> Result<(), String> {
        let mut f = Fields(body);
        let (_start, _end) = (f.u64()?, f.u64()?);
        let size = f.u64()?;
        let crc = f.u32()?;
        let compression = f.str()?;
        let n = f.u64()?;
        let compressed = f.bytes(usize::try_from(n).map_err(|_| "chunk too large")?)?;
        if size > MAX_CHUNK_BYTES {
            return Err(format!("chunk of {size} bytes exceeds {MAX_CHUNK_BYTES}"));
        }
        let mut records = std::mem::take(&mut self.chunk);
        records.clear();
        match compression.as_str() {
            "" => records.extend_from_slice(compressed),
            "zstd" => {
                records.reserve(size as usize);
                let z = match &mut self.zstd {
                    Some(z) => z,
                    None => self
                        .zstd
                        .insert(zstd::bulk::Decompressor::new().map_err(|e| e.to_string())?),
                };
                z.decompress_to_buffer(compressed, &mut records)
                    .map_err(|e| format!("zstd: {e}"))?;
            }
            other => return Err(format!("unsupported chunk compression {other:?}")),
        }
        if records.len() as u64 != size {
            return Err(format!("chunk holds {} bytes, not {size}", records.len()));
        }
        if crc != 0 && crc != crc32fast::hash(&records) {
            return Err("chunk CRC mismatch".into());
        }
        let mut inner = Fields(&records);
        self.chunk_index.clear();
        let total = records.len();
        let result = (|| {
            while !inner.0.is_empty() {
                let offset = (total - inner.0.len()) as u64;
                let opcode = inner.bytes(1)?[0];
                let len = inner.u64()?;
                let record = inner.bytes(usize::try_from(len).map_err(|_| "record too large")?)?;
                if opcode == op::MESSAGE {
                    let mut m = Fields(record);
                    let (channel, _sequence, log_time) = (m.u16()?, m.u32()?, m.u64()?);
                    let entries = self.chunk_index.entry(channel).or_default();
                    entries.push((log_time, offset));
                }
                self.record(opcode, record, visit)?;
            }
            Ok(())
        })();
        self.chunk = records;
        result
    }

    /// A message: telemetry waits for the truth of the same tick.
    fn message(&mut self, body: &[u8], visit: &mut impl Visit) -> Result<(), String> {
        let mut f = Fields(body);
        let channel = f.u16()?;
        let sequence = f.u32()?;
        let log_time = f.u64()?;
        let _publish = f.u64()?;
        let data = f.0;
        let time_ns = log_time.saturating_sub(self.epoch_ns);
        let topic = self
            .topics
            .get(&channel)
            .ok_or_else(|| {
                format!("a message on channel {channel}, which no Channel record declares")
            })?
            .as_str();
        let sized = |want: &[usize]| {
            if want.contains(&data.len()) {
                Ok(())
            } else {
                Err(format!(
                    "a {topic} message of {} bytes: its schema's are {want:?}",
                    data.len()
                ))
            }
        };
        match topic {
            TelemetryRecord::TOPIC => sized(&[
                TelemetryRecord::PAYLOAD_BYTES,
                crate::frame::LEGACY_TELEMETRY_BYTES,
            ])?,
            TruthRecord::TOPIC => sized(&[TruthRecord::PAYLOAD_BYTES])?,
            Overview::TOPIC => sized(&[Overview::PAYLOAD_BYTES])?,
            _ => {}
        }
        *self.per_channel.entry(channel).or_default() += 1;
        self.time_range = Some(self.time_range.map_or((log_time, log_time), |(a, b)| {
            (a.min(log_time), b.max(log_time))
        }));
        visit.message(topic, sequence, time_ns, data);
        match topic {
            TelemetryRecord::TOPIC => {
                self.messages += 1;
                self.pending = TelemetryRecord::decode(data)
                    .or_else(|| crate::frame::legacy_telemetry(data))
                    .map(|t| (sequence, time_ns, t));
            }
            TruthRecord::TOPIC => {
                self.messages += 1;
                if let (Some((seq, time_ns, telemetry)), Some(truth)) =
                    (self.pending.take(), TruthRecord::decode(data))
                {
                    if seq == sequence {
                        self.frames += 1;
                        self.last_time_ns = Some(time_ns);
                        visit.frame(&Frame {
                            time_ns,
                            telemetry,
                            truth,
                        });
                    }
                }
            }
            _ => {}
        }
        Ok(())
    }
}

/// A whole recording in memory: for small files and tests (use [`stream`] for runs of any
/// length).
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// The `run` metadata record.
    pub metadata: BTreeMap<String, String>,
    /// The `end` metadata record (how the run ended).
    pub end: BTreeMap<String, String>,
    /// Every frame, in order.
    pub frames: Vec<Frame>,
    /// What the read found.
    pub report: Option<ReadReport>,
}

impl Visit for Recording {
    fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
        match name {
            "run" => self.metadata = values.clone(),
            "end" => self.end = values.clone(),
            _ => {}
        }
    }

    fn frame(&mut self, frame: &Frame) {
        self.frames.push(*frame);
    }
}

/// Reads the whole of `path` into memory (see [`Recording`]).
pub fn read(path: &Path) -> Result<Recording, ReadError> {
    let mut rec = Recording::default();
    rec.report = Some(stream(path, &mut rec)?);
    Ok(rec)
}

/// The metadata records that describe where and when a run happened, not what it did:
/// comparisons of recordings leave them out.
pub const ENVIRONMENT_RECORDS: [&str; 2] = ["environment", "timing"];

/// SHA-256 over what a run did: every message (topic, sequence, time, payload), every
/// attachment and every metadata record but the [`ENVIRONMENT_RECORDS`] (the `run` record
/// holds the log-time epoch). Two runs of the same
/// seed and configuration have the same fingerprint.
pub fn fingerprint(path: &Path) -> Result<String, ReadError> {
    use sha2::{Digest, Sha256};
    struct Hash(Sha256);
    impl Hash {
        fn field(&mut self, bytes: &[u8]) {
            self.0.update((bytes.len() as u64).to_le_bytes());
            self.0.update(bytes);
        }
    }
    impl Visit for Hash {
        fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
            if !ENVIRONMENT_RECORDS.contains(&name) {
                self.field(name.as_bytes());
                for (k, v) in values {
                    self.field(k.as_bytes());
                    self.field(v.as_bytes());
                }
            }
        }
        fn attachment(&mut self, name: &str, data: &[u8]) {
            self.field(name.as_bytes());
            self.field(data);
        }
        fn message(&mut self, topic: &str, sequence: u32, time_ns: u64, data: &[u8]) {
            self.field(topic.as_bytes());
            self.0.update(sequence.to_le_bytes());
            self.0.update(time_ns.to_le_bytes());
            self.field(data);
        }
    }
    let mut h = Hash(Sha256::new());
    stream(path, &mut h)?;
    Ok(h.0.finalize().iter().map(|b| format!("{b:02x}")).collect())
}
