//! Reading a recording back as a stream (the official `mcap` crate's sans-io reader): constant
//! memory whatever the file's length, chunk CRCs checked, and unfinished files (a run that was
//! killed, a full disk) recovered up to their last complete record.

use crate::frame::{Frame, Telemetry, Truth};
use mcap::records::Record;
use mcap::sans_io::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::BTreeMap;
use std::io::Read;
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
    /// Not an MCAP file (its first records are unreadable).
    #[error("{path} is not an MCAP recording: {source}")]
    Mcap {
        /// File.
        path: PathBuf,
        /// Cause.
        source: mcap::McapError,
    },
}

/// What a reader is shown, in file order: the `run` metadata and the attachments before the
/// first frame, the `end` metadata after the last.
pub trait Visit {
    /// A metadata record.
    fn metadata(&mut self, _name: &str, _values: &BTreeMap<String, String>) {}
    /// An attachment (an input file of the run).
    fn attachment(&mut self, _name: &str, _data: &[u8]) {}
    /// One tick: telemetry and truth.
    fn frame(&mut self, frame: &Frame);
}

/// How far a file could be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FileState {
    /// Complete, with its summary and footer.
    Finished,
    /// It ends early (the run was killed or the disk filled): everything up to the last
    /// complete record was read.
    Unfinished,
    /// A record failed its check (a chunk CRC); the records before it were read.
    Corrupt {
        /// Bytes of the file read when the bad record was found (it lies before this offset).
        before_byte: u64,
        /// What failed.
        reason: String,
    },
}

/// What a read found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadReport {
    /// Messages read.
    pub messages: u64,
    /// Frames (tick pairs of telemetry and truth) read.
    pub frames: u64,
    /// Log time of the last frame, ns.
    pub last_time_ns: Option<u64>,
    /// Whether the file was complete.
    pub state: FileState,
}

impl std::fmt::Display for ReadReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let until = self.last_time_ns.map_or("nothing".to_string(), |t| {
            format!("t = {:.6} s", t as f64 * 1e-9)
        });
        match &self.state {
            FileState::Finished => write!(f, "complete, {} messages", self.messages),
            FileState::Unfinished => write!(
                f,
                "unfinished, {} messages recovered up to {until}",
                self.messages
            ),
            FileState::Corrupt {
                before_byte,
                reason,
            } => write!(
                f,
                "corrupt record before byte {before_byte} ({reason}); {} messages read up to {until}",
                self.messages
            ),
        }
    }
}

/// Streams `path` into `visit`. Errors only when the file cannot be opened or is not MCAP; a
/// truncated or corrupt file is read as far as it is intact and says so in the report.
pub fn stream(path: &Path, visit: &mut impl Visit) -> Result<ReadReport, ReadError> {
    let io = |source| ReadError::Io {
        path: path.to_owned(),
        source,
    };
    let mut file = std::fs::File::open(path).map_err(io)?;
    if !file.metadata().map_err(io)?.is_file() {
        return Err(io(std::io::Error::other("not a regular file")));
    }
    let mut reader = LinearReader::new_with_options(
        // Each chunk's CRC is checked before any of its records is shown (a chunk is at most
        // a few MiB): a corrupt chunk yields nothing, never garbage.
        LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    let mut s = Streamer::default();
    let mut fed = 0u64;
    let mut eof = false;
    let state = loop {
        let Some(event) = reader.next_event() else {
            break FileState::Finished;
        };
        match event {
            Ok(LinearReadEvent::ReadRequest(n)) => {
                if eof {
                    break if s.footer {
                        FileState::Finished
                    } else {
                        FileState::Unfinished
                    };
                }
                let buf = reader.insert(n.max(1 << 16));
                let got = file.read(buf).map_err(io)?;
                reader.notify_read(got);
                fed += got as u64;
                eof = got == 0;
            }
            Ok(LinearReadEvent::Record { data, opcode }) => {
                match mcap::parse_record(opcode, data) {
                    Ok(record) => s.record(record, visit),
                    Err(e) => break s.bad(fed, e, path)?,
                }
            }
            Err(e) => break s.bad(fed, e, path)?,
        }
    };
    Ok(ReadReport {
        messages: s.messages,
        frames: s.frames,
        last_time_ns: s.last_time_ns,
        state,
    })
}

/// Largest record accepted, bytes (a chunk is 4 MiB of records; attachments are input files).
pub const MAX_RECORD_BYTES: usize = 256 << 20;

/// Pairs the messages of a tick into frames.
#[derive(Default)]
struct Streamer {
    topics: BTreeMap<u16, String>,
    pending: Option<(u32, u64, Telemetry)>,
    messages: u64,
    frames: u64,
    last_time_ns: Option<u64>,
    footer: bool,
    anything: bool,
}

impl Streamer {
    fn record(&mut self, record: Record<'_>, visit: &mut impl Visit) {
        self.anything = true;
        match record {
            Record::Channel(c) => {
                self.topics.insert(c.id, c.topic);
            }
            Record::Metadata(m) => visit.metadata(&m.name, &m.metadata),
            Record::Attachment { header, data, .. } => visit.attachment(&header.name, &data),
            Record::Message { header, data } => {
                self.messages += 1;
                match self.topics.get(&header.channel_id).map(String::as_str) {
                    Some(Telemetry::TOPIC) => {
                        self.pending =
                            Telemetry::decode(&data).map(|t| (header.sequence, header.log_time, t));
                    }
                    Some(Truth::TOPIC) => {
                        if let (Some((seq, time_ns, telemetry)), Some(truth)) =
                            (self.pending.take(), Truth::decode(&data))
                        {
                            if seq == header.sequence {
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
            }
            Record::Footer(_) => self.footer = true,
            _ => {}
        }
    }

    /// A read error: before any record the file is not a recording; after some, the rest of
    /// the file is unusable and what was read stands.
    fn bad(&self, fed: u64, e: mcap::McapError, path: &Path) -> Result<FileState, ReadError> {
        if !self.anything {
            return Err(ReadError::Mcap {
                path: path.to_owned(),
                source: e,
            });
        }
        Ok(match e {
            mcap::McapError::UnexpectedEof | mcap::McapError::UnexpectedEoc => {
                FileState::Unfinished
            }
            other => FileState::Corrupt {
                before_byte: fed,
                reason: other.to_string(),
            },
        })
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
