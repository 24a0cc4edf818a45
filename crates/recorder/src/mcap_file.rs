//! An MCAP file writer that compresses whole chunks.
//!
//! The official `mcap` crate pushes every record of a chunk through a streaming compressor in
//! several small writes; at 400 000 messages per simulated second that costs more than the
//! compression itself. Here a chunk's records are encoded into one buffer, compressed in one
//! call (zstd) by a pool of compressors while the next chunk fills
//! ([`crate::compressors`]), and written, with their message indexes, in one write — in the
//! order the chunks were closed, so the bytes are those of compressing each on the spot.
//! The file carries everything an indexed reader (Foxglove's `McapIndexedReader`) needs:
//! message indexes after every chunk, and a summary with schemas, channels, statistics, chunk,
//! attachment and metadata indexes and summary offsets. After a failed write (a full disk, a
//! file size limit) the file can go back to its last chunk ([`McapFile::rewind`]) and still be
//! closed whole, shorter.
//!
//! Records follow the MCAP specification (<https://mcap.dev/spec>), little-endian throughout.

use crate::compressors::{gone, Compressors, Job};
use crate::mcap_format::{record, Put};
use crate::mcap_mark::{Counts, Mark, Marks};
use std::collections::{BTreeMap, VecDeque};
use std::io::{self, Write};
use std::sync::mpsc::{Receiver, TryRecvError};

pub use crate::mcap_format::{op, LIBRARY, MAGIC};

/// Where the bytes go: a file (made durable with `sync_data`) or a buffer.
pub trait Sink: Write {
    /// Asks the storage to keep what was written across a power loss.
    fn sync(&mut self) -> io::Result<()> {
        Ok(())
    }

    /// Cuts what was written back to its first `len` bytes; the next write goes there.
    fn truncate(&mut self, len: u64) -> io::Result<()>;
}

impl Sink for std::fs::File {
    fn sync(&mut self) -> io::Result<()> {
        self.sync_data()
    }

    fn truncate(&mut self, len: u64) -> io::Result<()> {
        use std::io::Seek;
        self.set_len(len)?;
        self.seek(io::SeekFrom::Start(len)).map(|_| ())
    }
}

impl Sink for Vec<u8> {
    fn truncate(&mut self, len: u64) -> io::Result<()> {
        Vec::truncate(self, usize::try_from(len).unwrap_or(usize::MAX));
        Ok(())
    }
}

/// The messages of the chunk being filled.
struct OpenChunk {
    records: Vec<u8>,
    /// Message index entries per channel id (`log_time`, offset in records: 16 bytes each,
    /// as they are written), in write order.
    index: Vec<Vec<u8>>,
    start_ns: u64,
    end_ns: u64,
}

impl OpenChunk {
    fn new(capacity: usize) -> Self {
        OpenChunk {
            records: Vec::with_capacity(capacity),
            index: Vec::new(),
            start_ns: u64::MAX,
            end_ns: 0,
        }
    }

    fn is_empty(&self) -> bool {
        self.records.is_empty()
    }
}

/// An MCAP file being written. Schemas, channels, metadata and attachments go straight to the
/// data section; messages collect in chunks ([`McapFile::message`]) that the caller closes
/// with [`McapFile::close_chunk`] (several chunks may be open at once, one per `lane`, so a
/// low-rate channel can live in chunks of its own); [`McapFile::finish`] writes the summary.
pub struct McapFile<W: Sink> {
    out: W,
    /// Bytes written to `out` so far (the offset of the next record).
    position: u64,
    /// Records waiting to be written (everything but chunk bodies).
    pending: Vec<u8>,
    /// Summary records by group.
    schemas: Vec<u8>,
    channels: Vec<u8>,
    chunk_indexes: Vec<u8>,
    attachment_indexes: Vec<u8>,
    metadata_indexes: Vec<u8>,
    schema_count: u16,
    channel_ids: Vec<u16>,
    counts: Counts,
    lanes: Vec<OpenChunk>,
    /// Bytes a chunk is expected to hold (the capacity of a fresh chunk buffer).
    chunk_bytes: usize,
    compressors: Compressors,
    /// Closed chunks being compressed, in the order they were closed.
    in_flight: VecDeque<InFlight>,
    /// At most this many chunks in flight (the memory the pipeline holds).
    max_in_flight: usize,
    /// Buffers of written chunks (records, compressed), for the next ones.
    spare: Vec<(Vec<u8>, Vec<u8>)>,
    /// CRC-32 of everything written so far (the data section's, until its end).
    data_crc: crc32fast::Hasher,
    /// Where the file can go back to ([`McapFile::rewind`]).
    marks: Marks,
}

/// A closed chunk (its records gone to a compressor) waiting for its frame.
struct InFlight {
    chunk: OpenChunk,
    done: Receiver<Job>,
}

/// Compressors in the pool: one per CPU, at most 4 (beyond, the writer's own encoding is the
/// limit).
fn compressor_count() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get().clamp(1, 4))
}

/// zstd level of the chunks: the fast end. Measured on the records of one simulated second of
/// the default run (26 MB in 0.5 MB chunks, noisy floats): level 1 → 11.4 MB in 79 ms,
/// −1 → 12.0 MB in 62 ms, −3 → 12.6 MB in 46 ms, −5 → 14.1 MB in 43 ms (lz4 → 14.1 MB in
/// 37 ms): −3 is the knee.
pub const ZSTD_LEVEL: i32 = -3;

impl<W: Sink> McapFile<W> {
    /// Starts a file: magic and header (`profile`, [`LIBRARY`]), written at once. `lanes`
    /// chunks can be open at the same time, each expected to hold up to `chunk_bytes`.
    pub fn create(out: W, profile: &str, lanes: usize, chunk_bytes: usize) -> io::Result<Self> {
        let compressors = compressor_count();
        let mut file = McapFile {
            out,
            position: 0,
            pending: Vec::with_capacity(1 << 16),
            schemas: Vec::new(),
            channels: Vec::new(),
            chunk_indexes: Vec::new(),
            attachment_indexes: Vec::new(),
            metadata_indexes: Vec::new(),
            schema_count: 0,
            channel_ids: Vec::new(),
            counts: Counts::default(),
            lanes: (0..lanes).map(|_| OpenChunk::new(chunk_bytes)).collect(),
            chunk_bytes,
            compressors: Compressors::start(compressors, ZSTD_LEVEL)?,
            in_flight: VecDeque::new(),
            max_in_flight: compressors + 1,
            spare: Vec::new(),
            data_crc: crc32fast::Hasher::new(),
            marks: Marks::default(),
        };
        file.write_head(profile)?;
        Ok(file)
    }

    /// Starts another file on `out` (as [`McapFile::create`]) with this closed one's
    /// compressors and buffers — a split recording's next part starts no threads and
    /// allocates no chunk buffers — and gives back the closed file's sink. On an error the
    /// new file holds less than its header (nothing to go back to).
    pub fn next_file(&mut self, out: W, profile: &str) -> io::Result<W> {
        assert!(
            self.in_flight.is_empty(),
            "a file is closed before the next"
        );
        let closed = std::mem::replace(&mut self.out, out);
        self.position = 0;
        self.pending.clear();
        for v in [
            &mut self.schemas,
            &mut self.channels,
            &mut self.chunk_indexes,
            &mut self.attachment_indexes,
            &mut self.metadata_indexes,
        ] {
            v.clear();
        }
        self.schema_count = 0;
        self.channel_ids.clear();
        self.counts = Counts::default();
        self.data_crc = crc32fast::Hasher::new();
        self.marks = Marks::default();
        self.write_head(profile)?;
        Ok(closed)
    }

    /// Magic and header (`profile`, [`LIBRARY`]), written at once.
    fn write_head(&mut self, profile: &str) -> io::Result<()> {
        let mut head = MAGIC.to_vec();
        record(&mut head, op::HEADER, |b| {
            b.str(profile).str(LIBRARY);
        });
        self.out.write_all(&head)?;
        self.data_crc.update(&head);
        self.position = head.len() as u64;
        Ok(())
    }

    /// Remembers the file as written so far as a point [`McapFile::rewind`] can go back to
    /// (each written chunk is one too).
    pub fn mark(&mut self) -> io::Result<()> {
        self.write_pending()?;
        self.marks.push(Mark {
            position: self.position,
            data_crc: self.data_crc.clone(),
            chunk_indexes: self.chunk_indexes.len(),
            attachment_indexes: self.attachment_indexes.len(),
            metadata_indexes: self.metadata_indexes.len(),
            counts: self.counts.clone(),
        });
        Ok(())
    }

    /// Goes back to the newest mark (forgetting it, so the next call goes further back):
    /// truncates the file there and drops every message since — chunks open, in flight or
    /// half written. False when no mark is left (the file is as it was).
    pub fn rewind(&mut self) -> io::Result<bool> {
        let Some(m) = self.marks.pop() else {
            return Ok(false);
        };
        self.in_flight.clear();
        for lane in &mut self.lanes {
            lane.records.clear();
            lane.index.clear();
            lane.start_ns = u64::MAX;
            lane.end_ns = 0;
        }
        self.pending.clear();
        self.out.truncate(m.position)?;
        self.position = m.position;
        self.data_crc = m.data_crc;
        self.chunk_indexes.truncate(m.chunk_indexes);
        self.attachment_indexes.truncate(m.attachment_indexes);
        self.metadata_indexes.truncate(m.metadata_indexes);
        self.counts = m.counts;
        Ok(true)
    }

    /// Log time of the last message the file holds (0 before any).
    pub fn end_ns(&self) -> u64 {
        self.counts.end_ns
    }

    /// Messages the file holds on channel `id` (in chunks written).
    pub fn messages_on(&self, id: u16) -> u64 {
        self.counts
            .per_channel
            .get(usize::from(id))
            .copied()
            .unwrap_or(0)
    }

    /// Offset in the file of the next record written.
    fn offset(&self) -> u64 {
        self.position + self.pending.len() as u64
    }

    /// Adds a schema (ids from 1) to the data section and the summary.
    pub fn schema(&mut self, id: u16, name: &str, encoding: &str, data: &[u8]) {
        let body = |b: &mut Vec<u8>| {
            b.u16(id).str(name).str(encoding).u32(data.len() as u32);
            b.extend_from_slice(data);
        };
        record(&mut self.pending, op::SCHEMA, body);
        record(&mut self.schemas, op::SCHEMA, body);
        self.schema_count += 1;
    }

    /// Adds a channel to the data section and the summary.
    pub fn channel(&mut self, id: u16, schema_id: u16, topic: &str, encoding: &str) {
        let body = |b: &mut Vec<u8>| {
            b.u16(id).u16(schema_id).str(topic).str(encoding).u32(0);
        };
        record(&mut self.pending, op::CHANNEL, body);
        record(&mut self.channels, op::CHANNEL, body);
        self.channel_ids.push(id);
        let per_channel = &mut self.counts.per_channel;
        per_channel.resize(per_channel.len().max(usize::from(id) + 1), 0);
    }

    /// Writes a metadata record (and indexes it).
    pub fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) -> io::Result<()> {
        self.drain()?;
        let offset = self.offset();
        record(&mut self.pending, op::METADATA, |b| {
            b.str(name).group32(|m| {
                for (k, v) in values {
                    m.str(k).str(v);
                }
            });
        });
        let length = self.offset() - offset;
        record(&mut self.metadata_indexes, op::METADATA_INDEX, |b| {
            b.u64(offset).u64(length).str(name);
        });
        self.counts.metadata += 1;
        self.write_pending()
    }

    /// Writes an attachment (with its CRC, and indexes it).
    pub fn attachment(
        &mut self,
        name: &str,
        media_type: &str,
        time_ns: u64,
        data: &[u8],
    ) -> io::Result<()> {
        self.drain()?;
        let offset = self.offset();
        record(&mut self.pending, op::ATTACHMENT, |b| {
            let at = b.len();
            b.u64(time_ns).u64(time_ns).str(name).str(media_type);
            b.u64(data.len() as u64);
            b.extend_from_slice(data);
            let crc = crc32fast::hash(&b[at..]);
            b.u32(crc);
        });
        let length = self.offset() - offset;
        record(&mut self.attachment_indexes, op::ATTACHMENT_INDEX, |b| {
            b.u64(offset).u64(length).u64(time_ns).u64(time_ns);
            b.u64(data.len() as u64).str(name).str(media_type);
        });
        self.counts.attachments += 1;
        self.write_pending()
    }

    /// Appends a message on a channel added with [`McapFile::channel`] to the open chunk of
    /// `lane` (the payload is written by `data`, into the chunk buffer: no copy). Returns the
    /// bytes the chunk holds now.
    #[inline]
    pub fn message(
        &mut self,
        lane: usize,
        channel_id: u16,
        sequence: u32,
        log_time: u64,
        data: impl FnOnce(&mut Vec<u8>),
    ) -> usize {
        let chunk = &mut self.lanes[lane];
        let offset = chunk.records.len() as u64;
        // Opcode, length (filled in below), channel, sequence, log and publish time.
        let mut head = [0u8; 1 + 8 + 2 + 4 + 8 + 8];
        head[0] = op::MESSAGE;
        head[9..11].copy_from_slice(&channel_id.to_le_bytes());
        head[11..15].copy_from_slice(&sequence.to_le_bytes());
        head[15..23].copy_from_slice(&log_time.to_le_bytes());
        head[23..31].copy_from_slice(&log_time.to_le_bytes());
        let records = &mut chunk.records;
        records.extend_from_slice(&head);
        data(records);
        let len = (records.len() as u64 - offset - 9).to_le_bytes();
        let at = offset as usize + 1;
        records[at..at + 8].copy_from_slice(&len);
        let channel = usize::from(channel_id);
        if chunk.index.len() <= channel {
            chunk.index.resize_with(channel + 1, Vec::new);
        }
        let mut entry = [0u8; 16];
        entry[..8].copy_from_slice(&log_time.to_le_bytes());
        entry[8..].copy_from_slice(&offset.to_le_bytes());
        chunk.index[channel].extend_from_slice(&entry);
        chunk.start_ns = chunk.start_ns.min(log_time);
        chunk.end_ns = chunk.end_ns.max(log_time);
        chunk.records.len()
    }

    /// Log time of the first message in the open chunk of `lane`, if it has any.
    pub fn chunk_start(&self, lane: usize) -> Option<u64> {
        let chunk = &self.lanes[lane];
        (!chunk.is_empty()).then_some(chunk.start_ns)
    }

    /// Hands the open chunk of `lane` to the compressors (nothing if it is empty) and writes
    /// the chunks whose frames are done, in the order they were closed, each with its message
    /// indexes in one write; waits for the oldest while too many are in flight.
    pub fn close_chunk(&mut self, lane: usize) -> io::Result<()> {
        if self.lanes[lane].is_empty() {
            return Ok(());
        }
        let (records, compressed) = self
            .spare
            .pop()
            .unwrap_or_else(|| (Vec::with_capacity(self.chunk_bytes), Vec::new()));
        let fresh = OpenChunk {
            records,
            ..OpenChunk::new(0)
        };
        let mut chunk = std::mem::replace(&mut self.lanes[lane], fresh);
        let records = std::mem::take(&mut chunk.records);
        let done = self.compressors.submit(Job::new(records, compressed))?;
        self.in_flight.push_back(InFlight { chunk, done });
        self.write_done()?;
        while self.in_flight.len() > self.max_in_flight {
            self.write_oldest()?;
        }
        Ok(())
    }

    /// Writes the chunks at the front of the queue whose frames are done.
    fn write_done(&mut self) -> io::Result<()> {
        loop {
            let job = match self.in_flight.front().map(|f| f.done.try_recv()) {
                Some(Ok(job)) => job,
                Some(Err(TryRecvError::Empty)) | None => return Ok(()),
                Some(Err(TryRecvError::Disconnected)) => return Err(gone()),
            };
            let f = self.in_flight.pop_front().expect("it has a front");
            self.write_chunk(f.chunk, job)?;
        }
    }

    /// Waits for the oldest chunk in flight and writes it.
    fn write_oldest(&mut self) -> io::Result<()> {
        let f = self.in_flight.pop_front().expect("a chunk is in flight");
        let job = f.done.recv().map_err(|_| gone())?;
        self.write_chunk(f.chunk, job)
    }

    /// Writes every chunk in flight (before any other record, so the order is the closing
    /// order).
    fn drain(&mut self) -> io::Result<()> {
        while !self.in_flight.is_empty() {
            self.write_oldest()?;
        }
        Ok(())
    }

    /// Writes `chunk` with its compressed frame from `job`, and its message indexes, in one
    /// write.
    fn write_chunk(&mut self, chunk: OpenChunk, job: Job) -> io::Result<()> {
        let Job {
            mut records,
            compressed,
            crc,
            result,
        } = job;
        result?;
        let start = self.offset();
        record(&mut self.pending, op::CHUNK, |b| {
            b.u64(chunk.start_ns).u64(chunk.end_ns);
            b.u64(records.len() as u64);
            b.u32(crc);
            b.str("zstd").u64(compressed.len() as u64);
            b.extend_from_slice(&compressed);
        });
        let chunk_length = self.offset() - start;
        let mut offsets = BTreeMap::new();
        let index_start = self.offset();
        for (channel, entries) in chunk.index.iter().enumerate() {
            if entries.is_empty() {
                continue;
            }
            let channel = channel as u16;
            offsets.insert(channel, self.offset());
            record(&mut self.pending, op::MESSAGE_INDEX, |b| {
                b.u16(channel).u32(entries.len() as u32);
                b.extend_from_slice(entries);
            });
        }
        let index_length = self.offset() - index_start;
        record(&mut self.chunk_indexes, op::CHUNK_INDEX, |b| {
            b.u64(chunk.start_ns)
                .u64(chunk.end_ns)
                .u64(start)
                .u64(chunk_length);
            b.group32(|m| {
                for (&channel, &offset) in &offsets {
                    m.u16(channel).u64(offset);
                }
            });
            b.u64(index_length).str("zstd");
            b.u64(compressed.len() as u64);
            b.u64(records.len() as u64);
        });
        // Counted as written (a mark's counts are the file's, not those of chunks still open).
        let c = &mut self.counts;
        for (channel, entries) in chunk.index.iter().enumerate() {
            let n = (entries.len() / 16) as u64;
            c.per_channel[channel] += n;
            c.messages += n;
        }
        c.chunks += 1;
        c.start_ns = Some(c.start_ns.map_or(chunk.start_ns, |s| s.min(chunk.start_ns)));
        c.end_ns = c.end_ns.max(chunk.end_ns);
        // Keep the buffers for the next chunks.
        records.clear();
        if self.spare.len() <= self.max_in_flight {
            self.spare.push((records, compressed));
        }
        self.mark()
    }

    fn write_pending(&mut self) -> io::Result<()> {
        self.out.write_all(&self.pending)?;
        self.data_crc.update(&self.pending);
        self.position += self.pending.len() as u64;
        self.pending.clear();
        Ok(())
    }

    /// Closes every open chunk, writes the data end, the summary (schemas, channels,
    /// statistics, chunk, attachment and metadata indexes, summary offsets) and the footer,
    /// and hands the sink back.
    pub fn finish(mut self) -> io::Result<W> {
        self.close()?;
        Ok(self.out)
    }

    /// The sink, as written so far (after [`McapFile::close`]: the finished file).
    pub fn into_sink(self) -> W {
        self.out
    }

    /// [`McapFile::finish`] in place: on failure the file can still [`McapFile::rewind`] and
    /// close again.
    pub fn close(&mut self) -> io::Result<()> {
        for lane in 0..self.lanes.len() {
            self.close_chunk(lane)?;
        }
        self.drain()?;
        // The data section's CRC covers every byte before the Data End record, from the
        // opening magic on (records still pending included).
        let mut crc = self.data_crc.clone();
        crc.update(&self.pending);
        let data_crc = crc.finalize();
        record(&mut self.pending, op::DATA_END, |b| {
            b.u32(data_crc);
        });
        let c = &self.counts;
        let mut statistics = Vec::new();
        record(&mut statistics, op::STATISTICS, |b| {
            b.u64(c.messages)
                .u16(self.schema_count)
                .u32(self.channel_ids.len() as u32);
            b.u32(c.attachments).u32(c.metadata).u32(c.chunks);
            b.u64(c.start_ns.unwrap_or(0)).u64(c.end_ns);
            b.group32(|m| {
                for &id in &self.channel_ids {
                    m.u16(id).u64(c.per_channel[usize::from(id)]);
                }
            });
        });
        let summary_start = self.offset();
        let mut summary = Vec::new();
        let mut offsets = Vec::new();
        for (opcode, group) in [
            (op::SCHEMA, &self.schemas),
            (op::CHANNEL, &self.channels),
            (op::STATISTICS, &statistics),
            (op::CHUNK_INDEX, &self.chunk_indexes),
            (op::ATTACHMENT_INDEX, &self.attachment_indexes),
            (op::METADATA_INDEX, &self.metadata_indexes),
        ] {
            if !group.is_empty() {
                offsets.push((opcode, summary_start + summary.len() as u64, group.len()));
                summary.extend_from_slice(group);
            }
        }
        let summary_offset_start = summary_start + summary.len() as u64;
        for (opcode, start, length) in offsets {
            record(&mut summary, op::SUMMARY_OFFSET, |b| {
                b.u8(opcode).u64(start).u64(length as u64);
            });
        }
        // The summary CRC covers the summary section and the footer up to the CRC field.
        summary.u8(op::FOOTER).u64(8 + 8 + 4);
        summary.u64(summary_start).u64(summary_offset_start);
        let crc = crc32fast::hash(&summary);
        summary.u32(crc);
        summary.extend_from_slice(MAGIC);
        self.pending.extend_from_slice(&summary);
        self.write_pending()?;
        self.out.flush()?;
        self.out.sync()
    }
}
