//! A finished recording's metadata and attachments read through its summary: the footer
//! points at the summary section, whose metadata and attachment indexes give each record's
//! offset. A few reads whatever the file's length — what a reader needs before it streams the
//! frames, when what it needs (the `end` record, files attached with it such as a controller
//! a `servo ctl load` swapped in) was written after them.

use crate::fields::Fields;
use crate::mcap_format::{op, MAGIC};
use crate::reader::{ReadError, Streamer, Visit, MAX_RECORD_BYTES};
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

/// Bytes of the footer record (opcode, length, summary start, summary offset start, CRC).
const FOOTER_BYTES: u64 = 1 + 8 + 8 + 8 + 4;
/// Largest summary section read (chunk indexes of a day-long recording fit many times).
const MAX_SUMMARY_BYTES: u64 = 256 << 20;

/// Shows `visit` every metadata record and attachment of the finished recording `path`, found
/// through its summary's indexes (in index order: attachments, then metadata). `Ok(false)`
/// when the file has no summary to find them by (an unfinished file: stream it instead); an
/// index pointing outside the file, or a record that fails its check, is an error naming the
/// file.
pub fn visit_indexed(path: &Path, visit: &mut impl Visit) -> Result<bool, ReadError> {
    let io = |source| ReadError::Io {
        path: path.to_owned(),
        source,
    };
    let damaged = |reason: String| ReadError::Damaged {
        path: path.to_owned(),
        reason,
    };
    let (mut file, len) = daq_io::input_file::open_regular(path, u64::MAX).map_err(io)?;
    let magic_at = match len.checked_sub(MAGIC.len() as u64 + FOOTER_BYTES) {
        Some(footer_at) if footer_at >= MAGIC.len() as u64 => footer_at + FOOTER_BYTES,
        _ => return Ok(false),
    };
    let mut tail = [0u8; (FOOTER_BYTES + 8) as usize];
    file.seek(SeekFrom::Start(magic_at - FOOTER_BYTES))
        .map_err(io)?;
    file.read_exact(&mut tail).map_err(io)?;
    if &tail[FOOTER_BYTES as usize..] != MAGIC || tail[0] != op::FOOTER {
        return Ok(false);
    }
    let mut footer = Fields(&tail[9..]);
    let (summary_start, offsets_start) = (footer.u64(), footer.u64());
    let (Ok(summary_start), Ok(offsets_start)) = (summary_start, offsets_start) else {
        return Ok(false);
    };
    if summary_start == 0 {
        return Ok(false);
    }
    let summary_end = if offsets_start == 0 {
        magic_at - FOOTER_BYTES
    } else {
        offsets_start
    };
    let summary = read_at(&mut file, summary_start, summary_end, MAX_SUMMARY_BYTES)
        .map_err(|e| damaged(format!("summary section: {e}")))?;
    let mut records = Vec::new();
    let mut s = Fields(&summary);
    while !s.is_empty() {
        let opcode = s.u8().map_err(&damaged)?;
        let n = s.u64().map_err(&damaged)?;
        let mut body = Fields(
            s.bytes(usize::try_from(n).unwrap_or(usize::MAX))
                .map_err(&damaged)?,
        );
        if opcode == op::ATTACHMENT_INDEX || opcode == op::METADATA_INDEX {
            let offset = body.u64().map_err(&damaged)?;
            let length = body.u64().map_err(&damaged)?;
            records.push((offset, length));
        }
    }
    let mut streamer = Streamer::default();
    for (offset, length) in records {
        let end = offset.saturating_add(length);
        if end > summary_start {
            return Err(damaged(format!(
                "an index points at bytes {offset}–{end}, past the data section's end at {summary_start}"
            )));
        }
        let record = read_at(&mut file, offset, end, MAX_RECORD_BYTES + 9)
            .map_err(|e| damaged(format!("record at byte {offset}: {e}")))?;
        let Some((&opcode, rest)) = record.split_first() else {
            return Err(damaged(format!("empty record at byte {offset}")));
        };
        let body = rest
            .get(8..)
            .ok_or_else(|| damaged(format!("record at byte {offset} too short")))?;
        streamer
            .record(opcode, body, visit)
            .map_err(|e| damaged(format!("record at byte {offset}: {e}")))?;
    }
    Ok(true)
}

/// Bytes `from..to` of `file`, at most `limit` of them.
fn read_at(file: &mut std::fs::File, from: u64, to: u64, limit: u64) -> Result<Vec<u8>, String> {
    let n = to
        .checked_sub(from)
        .filter(|&n| n <= limit)
        .ok_or_else(|| format!("bytes {from}–{to} are not a range of at most {limit}"))?;
    file.seek(SeekFrom::Start(from))
        .map_err(|e| e.to_string())?;
    let mut buf = vec![0; usize::try_from(n).map_err(|e| e.to_string())?];
    file.read_exact(&mut buf).map_err(|e| e.to_string())?;
    Ok(buf)
}
