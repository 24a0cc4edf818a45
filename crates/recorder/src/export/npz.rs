//! NumPy `.npz`: a zip archive of `.npy` arrays, one per column. The columns are spooled to
//! temporary files in a private folder beside the output while the recording streams (the
//! `.npy` header needs the length), then stored (uncompressed, zip64) into the archive.

use super::{Column, Kind, Rows, Table};
use crate::placement::create_private;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::Path;

/// A column being spooled.
struct Spool {
    name: String,
    kind: Kind,
    file: BufWriter<File>,
    len: u64,
}

/// The columns of every table, spooled.
pub(crate) struct NpzRows {
    path: std::path::PathBuf,
    /// Holds the spooled columns; removed when dropped.
    _dir: tempfile::TempDir,
    tables: Vec<(Table, Vec<Spool>)>,
}

impl NpzRows {
    pub(crate) fn create(path: &Path, tables: &[(Table, Vec<Column>)]) -> std::io::Result<Self> {
        let parent = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let dir = tempfile::Builder::new()
            .prefix(".fts-export-")
            .tempdir_in(parent)?;
        let mut spooled = Vec::new();
        for (table, columns) in tables {
            let mut spools = Vec::new();
            for (i, c) in columns.iter().enumerate() {
                let file = File::options()
                    .read(true)
                    .write(true)
                    .create_new(true)
                    .open(dir.path().join(format!("{}-{i}", spooled.len())))?;
                spools.push(Spool {
                    name: c.name.clone(),
                    kind: c.kind,
                    file: BufWriter::with_capacity(1 << 16, file),
                    len: 0,
                });
            }
            spooled.push((*table, spools));
        }
        // The output itself, claimed now so a clash fails before the work.
        create_private(path)?;
        Ok(NpzRows {
            path: path.to_owned(),
            _dir: dir,
            tables: spooled,
        })
    }
}

impl Rows for NpzRows {
    fn row(&mut self, table: Table, values: &[f64]) -> std::io::Result<()> {
        let Some((_, spools)) = self.tables.iter_mut().find(|(t, _)| *t == table) else {
            return Ok(());
        };
        for (s, &v) in spools.iter_mut().zip(values) {
            match s.kind {
                Kind::F64 => s.file.write_all(&v.to_le_bytes())?,
                Kind::F32 => s.file.write_all(&(v as f32).to_le_bytes())?,
                Kind::U32 => s.file.write_all(&(v as u32).to_le_bytes())?,
            }
            s.len += 1;
        }
        Ok(())
    }

    /// Writes the archive: each column as `<name>.npy` (`numpy.load(f)["time_s"]`).
    fn finish(self: Box<Self>) -> std::io::Result<()> {
        let file = File::options()
            .write(true)
            .truncate(true)
            .open(&self.path)?;
        let mut zip = zip::ZipWriter::new(BufWriter::with_capacity(1 << 20, file));
        let options = zip::write::SimpleFileOptions::default()
            .compression_method(zip::CompressionMethod::Stored)
            .large_file(true);
        for (_, spools) in self.tables {
            for s in spools {
                let mut spooled = s.file.into_inner().map_err(|e| e.into_error())?;
                spooled.seek(SeekFrom::Start(0))?;
                zip.start_file(format!("{}.npy", s.name), options)
                    .map_err(std::io::Error::other)?;
                zip.write_all(&npy_header(s.kind, s.len))?;
                std::io::copy(&mut spooled, &mut zip)?;
            }
        }
        let mut out = zip.finish().map_err(std::io::Error::other)?;
        out.flush()?;
        out.get_ref().sync_data()
    }
}

/// The `.npy` (version 1.0) header of a one-dimensional little-endian array of `len` values,
/// padded so the data starts 64-aligned.
fn npy_header(kind: Kind, len: u64) -> Vec<u8> {
    let descr = match kind {
        Kind::F64 => "<f8",
        Kind::F32 => "<f4",
        Kind::U32 => "<u4",
    };
    let mut dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': ({len},), }}");
    let unpadded = 10 + dict.len() + 1;
    dict.push_str(&" ".repeat(unpadded.next_multiple_of(64) - unpadded));
    dict.push('\n');
    let mut h = b"\x93NUMPY\x01\x00".to_vec();
    h.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    h.extend_from_slice(dict.as_bytes());
    h
}
