//! Every byte of a finished recording checked, beyond the chunk payloads the [`Streamer`]
//! decodes: the data section's CRC (Data End), each chunk's message indexes against the
//! messages the chunk holds, the summary's CRC (footer), its copies of the schemas and
//! channels, its statistics, chunk, attachment and metadata indexes and summary offsets
//! against what the data section held, the footer's offsets and the closing magic.
//!
//! A file whose header names [`LIBRARY`] was written with every CRC; in it a zero CRC is
//! damage. Other files (ours before that, or another writer's) may leave a CRC at zero, which
//! the MCAP specification reads as "not computed".
//!
//! [`Streamer`]: crate::reader::Streamer

use crate::fields::Fields;
use crate::mcap_format::{op, LIBRARY};
use std::collections::BTreeMap;

/// Log time and offset in the chunk's records of each message, per channel id: what the
/// chunk's message indexes must say.
pub(crate) type ChunkIndex = BTreeMap<u16, Vec<(u64, u64)>>;

/// What the data section held, as its records went by.
#[derive(Default)]
pub(crate) struct Ledger {
    /// The header's `library`.
    library: Option<String>,
    /// Schema and channel record bodies by id.
    schemas: BTreeMap<u16, Vec<u8>>,
    channels: BTreeMap<u16, Vec<u8>>,
    /// Each chunk, in file order.
    chunks: Vec<ChunkEntry>,
    /// What the message indexes after the last chunk must still say (None: that chunk could
    /// not be read, so its indexes cannot be checked).
    expected_index: Option<ChunkIndex>,
    /// Attachment and metadata records: offset, length, name.
    attachments: Vec<(u64, u64, String)>,
    metadata: Vec<(u64, u64, String)>,
    /// Where the summary starts (after the Data End record).
    summary_start: Option<u64>,
    /// The summary's bytes so far, for its CRC.
    summary_crc: Option<crc32fast::Hasher>,
    /// Consecutive runs of one opcode in the summary: opcode, start, length.
    groups: Vec<(u8, u64, u64)>,
    /// Where the summary offsets start.
    summary_offsets_start: Option<u64>,
    /// Summary records seen, by opcode.
    summary_seen: BTreeMap<u8, usize>,
    /// A record of the data section was already found damaged (the data section's CRC and
    /// the statistics then fail as a consequence, and are not reported again).
    data_damaged: bool,
}

/// One chunk as the data section held it.
struct ChunkEntry {
    start_ns: u64,
    end_ns: u64,
    offset: u64,
    length: u64,
    compression: String,
    compressed_size: u64,
    uncompressed_size: u64,
    index_offsets: BTreeMap<u16, u64>,
    index_length: u64,
}

/// What the messages came to, for the statistics.
pub(crate) struct Counts<'a> {
    /// Messages per channel id.
    pub per_channel: &'a BTreeMap<u16, u64>,
    /// Earliest and latest log time.
    pub time_range: Option<(u64, u64)>,
}

impl Ledger {
    /// Whether the file was written with every CRC (a zero CRC in it is damage).
    fn checked(&self) -> bool {
        self.library.as_deref() == Some(LIBRARY)
    }

    /// A record of the data section at `at` (not Data End); `index` is the message index of
    /// the chunk just decoded (for a Chunk record; None if it could not be read).
    pub(crate) fn data_record(
        &mut self,
        at: u64,
        opcode: u8,
        body: &[u8],
        index: Option<ChunkIndex>,
    ) -> Result<(), String> {
        if opcode != op::MESSAGE_INDEX {
            self.index_complete()?;
        }
        let mut f = Fields(body);
        let length = 9 + body.len() as u64;
        match opcode {
            op::HEADER if at == 8 => {
                let _profile = f.str()?;
                self.library = Some(f.str()?);
            }
            op::HEADER => return Err("a second Header record".into()),
            _ if at == 8 => return Err("the first record is not a Header".into()),
            op::SCHEMA => {
                let id = f.u16()?;
                self.schemas.insert(id, body.to_vec());
            }
            op::CHANNEL => {
                let id = f.u16()?;
                self.channels.insert(id, body.to_vec());
            }
            op::ATTACHMENT => {
                let (_log, _create) = (f.u64()?, f.u64()?);
                self.attachments.push((at, length, f.str()?));
                let tail = body.len().checked_sub(4).ok_or("record too short")?;
                let crc = u32::from_le_bytes(body[tail..].try_into().expect("4"));
                if crc == 0 && self.checked() {
                    return Err("attachment CRC missing (zero)".into());
                }
            }
            op::METADATA => self.metadata.push((at, length, f.str()?)),
            op::CHUNK => {
                let (start_ns, end_ns) = (f.u64()?, f.u64()?);
                let uncompressed_size = f.u64()?;
                let crc = f.u32()?;
                let compression = f.str()?;
                let compressed_size = f.u64()?;
                self.chunks.push(ChunkEntry {
                    start_ns,
                    end_ns,
                    offset: at,
                    length,
                    compression,
                    compressed_size,
                    uncompressed_size,
                    index_offsets: BTreeMap::new(),
                    index_length: 0,
                });
                self.expected_index = index;
                if crc == 0 && self.checked() {
                    return Err("chunk CRC missing (zero)".into());
                }
            }
            op::MESSAGE_INDEX => {
                let chunk = self
                    .chunks
                    .last_mut()
                    .ok_or("a message index before any chunk")?;
                let channel = f.u16()?;
                chunk.index_offsets.insert(channel, at);
                chunk.index_length += length;
                // An array: its length in bytes, then (log time, offset) pairs.
                let n = f.u32()? as usize;
                let mut pairs = Fields(f.bytes(n)?);
                let mut entries = Vec::with_capacity(n / 16);
                while !pairs.is_empty() {
                    entries.push((pairs.u64()?, pairs.u64()?));
                }
                if let Some(expected) = &mut self.expected_index {
                    match expected.remove(&channel) {
                        Some(e) if e == entries => {}
                        Some(_) => {
                            return Err(format!(
                                "message index of channel {channel} disagrees with its chunk"
                            ))
                        }
                        None => {
                            return Err(format!(
                                "message index of channel {channel}, which its chunk does not hold"
                            ))
                        }
                    }
                }
            }
            op::FOOTER => return Err("a footer before the Data End record".into()),
            _ => {}
        }
        Ok(())
    }

    /// Every channel of the last chunk has had its message index.
    fn index_complete(&mut self) -> Result<(), String> {
        match self.expected_index.take() {
            Some(rest) if !rest.is_empty() => Err(format!(
                "the chunk at byte {} has no message index for channel(s) {:?}",
                self.chunks.last().map_or(0, |c| c.offset),
                rest.keys().collect::<Vec<_>>()
            )),
            _ => Ok(()),
        }
    }

    /// The Data End record at `at`, `computed` the CRC of every byte before it, `damaged`
    /// whether a record before it failed its own check; the summary starts after it.
    pub(crate) fn data_end(
        &mut self,
        at: u64,
        body: &[u8],
        computed: u32,
        damaged: bool,
    ) -> Result<(), String> {
        self.data_damaged = damaged;
        self.summary_start = Some(at + 9 + body.len() as u64);
        self.summary_crc = Some(crc32fast::Hasher::new());
        self.index_complete()?;
        let crc = Fields(body).u32()?;
        match crc {
            0 if self.checked() => Err("data section CRC missing (zero)".into()),
            0 => Ok(()),
            c if c != computed && !damaged => Err(
                "data section CRC mismatch: damage outside the chunk payloads (header, schemas, channels, message indexes, metadata or attachments)"
                    .into(),
            ),
            _ => Ok(()),
        }
    }

    /// Whether the data section has ended (a Data End record was read).
    pub(crate) fn in_summary(&self) -> bool {
        self.summary_start.is_some()
    }

    /// A record of the summary section at `at` (not the footer), `head` its opcode and length.
    pub(crate) fn summary_record(
        &mut self,
        at: u64,
        head: &[u8],
        body: &[u8],
        counts: &Counts,
    ) -> Result<(), String> {
        if let Some(h) = &mut self.summary_crc {
            h.update(head);
            h.update(body);
        }
        let opcode = head[0];
        let length = 9 + body.len() as u64;
        match self.groups.last_mut() {
            Some((o, start, len)) if *o == opcode && *start + *len == at => *len += length,
            _ => self.groups.push((opcode, at, length)),
        }
        let n = self.summary_seen.entry(opcode).or_default();
        let nth = *n;
        *n += 1;
        if opcode != op::SUMMARY_OFFSET && self.summary_offsets_start.is_some() {
            return Err("a summary record after the summary offsets".into());
        }
        let mut f = Fields(body);
        let copy = |what: &str, of: &BTreeMap<u16, Vec<u8>>, f: &mut Fields| {
            let id = f.u16()?;
            match of.get(&id) {
                Some(b) if b == body => Ok(()),
                _ => Err(format!(
                    "the summary's {what} {id} differs from the data section's"
                )),
            }
        };
        match opcode {
            op::SCHEMA => copy("schema", &self.schemas, &mut f)?,
            op::CHANNEL => copy("channel", &self.channels, &mut f)?,
            op::STATISTICS if !self.data_damaged => self.statistics(&mut f, counts)?,
            op::STATISTICS => {}
            op::CHUNK_INDEX => self.chunk_index(nth, &mut f)?,
            op::ATTACHMENT_INDEX => {
                let (offset, len) = (f.u64()?, f.u64()?);
                let (_log, _create, _size) = (f.u64()?, f.u64()?, f.u64()?);
                let want = self
                    .attachments
                    .get(nth)
                    .ok_or("an attachment index too many")?;
                if *want != (offset, len, f.str()?) {
                    return Err(format!(
                        "attachment index {nth} disagrees with the data section"
                    ));
                }
            }
            op::METADATA_INDEX => {
                let (offset, len) = (f.u64()?, f.u64()?);
                let want = self.metadata.get(nth).ok_or("a metadata index too many")?;
                if *want != (offset, len, f.str()?) {
                    return Err(format!(
                        "metadata index {nth} disagrees with the data section"
                    ));
                }
            }
            op::SUMMARY_OFFSET => {
                self.summary_offsets_start.get_or_insert(at);
                let (group, start, len) = (f.u8()?, f.u64()?, f.u64()?);
                if !self.groups.contains(&(group, start, len)) {
                    return Err(format!(
                        "summary offset for opcode {group:#04x} points at no such group"
                    ));
                }
            }
            other => return Err(format!("record opcode {other:#04x} in the summary")),
        }
        Ok(())
    }

    /// The statistics record against the messages read.
    fn statistics(&self, f: &mut Fields, counts: &Counts) -> Result<(), String> {
        let messages = f.u64()?;
        let schemas = f.u16()?;
        let channels = f.u32()?;
        let (attachments, metadata, chunks) = (f.u32()?, f.u32()?, f.u32()?);
        let (start, end) = (f.u64()?, f.u64()?);
        let n = f.u32()? as usize;
        let mut per = Fields(f.bytes(n)?);
        let mut per_channel = BTreeMap::new();
        while !per.is_empty() {
            let id = per.u16()?;
            per_channel.insert(id, per.u64()?);
        }
        let read: u64 = counts.per_channel.values().sum();
        let nonzero = |m: &BTreeMap<u16, u64>| {
            m.iter()
                .filter(|(_, n)| **n > 0)
                .map(|(k, n)| (*k, *n))
                .collect::<Vec<_>>()
        };
        let (first, last) = counts.time_range.unwrap_or((0, 0));
        let agree = messages == read
            && usize::from(schemas) == self.schemas.len()
            && channels as usize == self.channels.len()
            && attachments as usize == self.attachments.len()
            && metadata as usize == self.metadata.len()
            && chunks as usize == self.chunks.len()
            && nonzero(&per_channel) == nonzero(counts.per_channel)
            && (messages == 0 || (start, end) == (first, last));
        if agree {
            Ok(())
        } else {
            Err(format!(
                "the statistics ({messages} messages, {chunks} chunks) disagree with the file ({read} messages, {} chunks read)",
                self.chunks.len()
            ))
        }
    }

    /// The `nth` chunk index against the `nth` chunk.
    fn chunk_index(&self, nth: usize, f: &mut Fields) -> Result<(), String> {
        let c = self.chunks.get(nth).ok_or("a chunk index too many")?;
        let (start_ns, end_ns, offset, length) = (f.u64()?, f.u64()?, f.u64()?, f.u64()?);
        let n = f.u32()? as usize;
        let mut m = Fields(f.bytes(n)?);
        let mut offsets = BTreeMap::new();
        while !m.is_empty() {
            let id = m.u16()?;
            offsets.insert(id, m.u64()?);
        }
        let index_length = f.u64()?;
        let compression = f.str()?;
        let (compressed, uncompressed) = (f.u64()?, f.u64()?);
        let agree = (start_ns, end_ns, offset, length)
            == (c.start_ns, c.end_ns, c.offset, c.length)
            && offsets == c.index_offsets
            && index_length == c.index_length
            && compression == c.compression
            && (compressed, uncompressed) == (c.compressed_size, c.uncompressed_size);
        if agree {
            Ok(())
        } else {
            Err(format!(
                "chunk index {nth} disagrees with the chunk at byte {}",
                c.offset
            ))
        }
    }

    /// The footer at `at`: its offsets, its CRC over the summary, and that every schema,
    /// channel and chunk has its summary copy.
    pub(crate) fn footer(&mut self, at: u64, head: &[u8], body: &[u8]) -> Result<(), String> {
        let mut f = Fields(body);
        let (summary_start, offsets_start) = (f.u64()?, f.u64()?);
        let crc = f.u32()?;
        let mut h = self.summary_crc.take().unwrap_or_default();
        h.update(head);
        h.update(&body[..16]);
        let empty = self.groups.is_empty();
        let want_start = if empty {
            0
        } else {
            self.summary_start.unwrap_or(0)
        };
        if summary_start != want_start || offsets_start != self.summary_offsets_start.unwrap_or(0) {
            return Err(format!(
                "the footer's summary offsets ({summary_start}, {offsets_start}) are not where the summary is"
            ));
        }
        match crc {
            0 if self.checked() => return Err("summary CRC missing (zero)".into()),
            0 => {}
            c if c != h.finalize() => return Err("summary CRC mismatch".into()),
            _ => {}
        }
        let seen = |o: u8| self.summary_seen.get(&o).copied().unwrap_or(0);
        if self.checked()
            && (seen(op::SCHEMA) != self.schemas.len()
                || seen(op::CHANNEL) != self.channels.len()
                || seen(op::CHUNK_INDEX) != self.chunks.len()
                || seen(op::STATISTICS) != 1
                || seen(op::ATTACHMENT_INDEX) != self.attachments.len()
                || seen(op::METADATA_INDEX) != self.metadata.len())
        {
            return Err(format!(
                "the summary ending at byte {at} lacks a copy or an index of the data section's records"
            ));
        }
        Ok(())
    }
}
