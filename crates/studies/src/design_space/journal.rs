//! Where a study's points go as they finish, so that an interrupted study resumes where it
//! stopped: the study folder holds the description (`study.toml`, the study's identity) and one
//! journal per shard (`points-<i>-of-<N>.csv`), each row appended and flushed as its point
//! finishes. A folder that holds another study is refused, never overwritten.

use super::evaluate::Point;
use super::spec::Study;
use super::table::{header, parse_row, row};
use crate::error::StudyError;
use run_config::sha256_hex;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};

/// Name of the study's description in its folder.
pub const DESCRIPTION: &str = "study.toml";

/// Largest journal read back, bytes (a line per point of a few hundred bytes: millions of
/// points).
pub const MAX_JOURNAL_BYTES: u64 = 1 << 30;

/// One deterministic slice of a study: points `i` with `i mod count = index − 1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1-based shard number.
    pub index: u64,
    /// Number of shards.
    pub count: u64,
}

impl Shard {
    /// The whole study.
    pub const ALL: Shard = Shard { index: 1, count: 1 };

    /// Parses `i/N` (1 ≤ i ≤ N ≤ 100 000); the error is the allowed form.
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad = || "i/N with 1 ≤ i ≤ N ≤ 100000 (e.g. 3/8)".to_owned();
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            i.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if !(1..=count).contains(&index) || count > 100_000 {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// Whether point `i` belongs to this shard.
    pub fn contains(&self, i: u64) -> bool {
        i % self.count == self.index - 1
    }

    /// The points of this shard in a study of `points` points.
    pub fn points(&self, points: u64) -> impl Iterator<Item = u64> + '_ {
        (self.index - 1..points).step_by(self.count as usize)
    }

    /// The journal's file name.
    pub fn file_name(&self) -> String {
        format!("points-{}-of-{}.csv", self.index, self.count)
    }

    /// The shard whose journal is named `name` ([`Shard::file_name`]), if it is one.
    pub fn of_file_name(name: &str) -> Option<Shard> {
        let (i, n) = name
            .strip_prefix("points-")?
            .strip_suffix(".csv")?
            .split_once("-of-")?;
        Shard::parse(&format!("{i}/{n}")).ok()
    }
}

/// The shard journals in the study folder `dir`, with their shards.
pub fn journals(dir: &Path) -> Result<Vec<(PathBuf, Shard)>, StudyError> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io(dir))? {
        let path = entry.map_err(io(dir))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if let Some(shard) = Shard::of_file_name(name) {
            out.push((path, shard));
        }
    }
    out.sort_by_key(|(_, s)| (s.count, s.index));
    Ok(out)
}

/// An I/O error on `path` as a study error.
pub(super) fn io(path: &Path) -> impl FnOnce(std::io::Error) -> StudyError + '_ {
    move |source| {
        crate::report::ReportError::Io {
            path: path.to_owned(),
            source,
        }
        .into()
    }
}

/// A study file or folder that cannot be used (`what` says why).
pub(super) fn foreign(path: &Path, what: String) -> StudyError {
    StudyError::DataFile {
        path: path.to_owned(),
        line: 1,
        what,
    }
}

/// Makes `dir` the folder of `study`: creates it with the description, or checks that the
/// description already there is this study's.
pub fn claim(study: &Study, dir: &Path) -> Result<(), StudyError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    let path = dir.join(DESCRIPTION);
    match daq_io::input_file::read_regular(&path, run_config::input_file::MAX_TEXT_BYTES) {
        Ok(held) if sha256_hex(&held) == study.sha256 => Ok(()),
        Ok(held) => Err(foreign(
            &path,
            format!(
                "this folder holds another study (SHA-256 {}, this one {}): choose another output folder, or remove this one to start over",
                &sha256_hex(&held)[..12],
                &study.sha256[..12]
            ),
        )),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let mut f = OpenOptions::new()
                .write(true)
                .create_new(true)
                .open(&path)
                .map_err(io(&path))?;
            f.write_all(study.text.as_bytes()).map_err(io(&path))
        }
        Err(e) => Err(io(&path)(e)),
    }
}

/// The points of `shard` that `done` (a journal's points) does not hold, in index order.
pub fn pending(study: &Study, shard: Shard, done: &[Point]) -> Vec<u64> {
    let held: std::collections::HashSet<u64> = done.iter().map(|p| p.index).collect();
    shard
        .points(study.points())
        .filter(|i| !held.contains(i))
        .collect()
}

/// A shard's journal, open for appending.
pub struct Journal {
    file: File,
    path: PathBuf,
}

impl Journal {
    /// Opens (or starts) `shard`'s journal in the study folder `dir` (claimed with [`claim`]);
    /// returns it with the points it already holds. A last line cut short by an interruption is
    /// dropped (its point runs again).
    pub fn open(
        study: &Study,
        dir: &Path,
        shard: Shard,
    ) -> Result<(Journal, Vec<Point>), StudyError> {
        let path = dir.join(shard.file_name());
        let head = header(study);
        let (done, keep) = match daq_io::input_file::read_regular(&path, MAX_JOURNAL_BYTES) {
            Ok(bytes) => read_journal(study, &path, &bytes, shard)?,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => (Vec::new(), 0),
            Err(e) => return Err(io(&path)(e)),
        };
        let mut file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .read(true)
            .write(true)
            .open(&path)
            .map_err(io(&path))?;
        file.set_len(keep).map_err(io(&path))?;
        if keep == 0 {
            file.write_all(format!("{head}\n").as_bytes())
                .map_err(io(&path))?;
        }
        use std::io::Seek;
        file.seek(std::io::SeekFrom::End(0)).map_err(io(&path))?;
        Ok((Journal { file, path }, done))
    }

    /// Appends a finished point (one write of one whole line).
    pub fn append(&mut self, p: &Point) -> Result<(), StudyError> {
        self.file
            .write_all(row(p).as_bytes())
            .map_err(io(&self.path))
    }

    /// Flushes the journal to the disk.
    pub fn sync(&mut self) -> Result<(), StudyError> {
        self.file.sync_data().map_err(io(&self.path))
    }
}

/// The points of a journal's `bytes` and the length of its complete lines in bytes. A torn
/// last line (what a crash mid-write leaves: no newline, perhaps a character cut in two) is
/// dropped, so its point is computed again; a complete line that is not a point of this shard
/// is refused.
pub fn read_journal(
    study: &Study,
    path: &Path,
    bytes: &[u8],
    shard: Shard,
) -> Result<(Vec<Point>, u64), StudyError> {
    let head = header(study);
    let mut done = Vec::new();
    let mut keep = 0u64;
    let complete = match bytes.iter().rposition(|&b| b == b'\n') {
        Some(end) => &bytes[..=end],
        None => &[],
    };
    let complete = std::str::from_utf8(complete).map_err(|e| StudyError::DataFile {
        path: path.to_owned(),
        line: complete[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count()
            + 1,
        what: "not UTF-8 text".into(),
    })?;
    for (n, line) in complete.lines().enumerate() {
        if n == 0 {
            if line != head {
                return Err(foreign(
                    path,
                    "the journal's header is not this study's".into(),
                ));
            }
        } else {
            let p = parse_row(study, line)
                .filter(|p| shard.contains(p.index) && p.index < study.points())
                .ok_or_else(|| StudyError::DataFile {
                    path: path.to_owned(),
                    line: n + 1,
                    what: format!(
                        "not a point of shard {}/{} of this study",
                        shard.index, shard.count
                    ),
                })?;
            done.push(p);
        }
        keep += line.len() as u64 + 1;
    }
    Ok((done, keep))
}
