//! Exporting a recording to files any tool loads: CSV, or NumPy `.npz` (one array per
//! column, loaded by `numpy.load` without the MCAP packages). Streams in constant memory
//! whatever the recording's length (the `.npz` columns are spooled to temporary files beside
//! the output), with topic selection, a time window and decimation; works on unfinished
//! recordings too. The output is written under a temporary name and never replaces an
//! existing file unless asked.

mod csv;
mod npz;

use crate::error::RecordError;
use crate::frame::{Frame, Message, TelemetryRecord, TruthRecord};
use crate::overview::{Overview, Signals};
use crate::placement::Overwrite;
use crate::reader::{stream, ReadError, ReadReport, Visit};
use std::path::{Path, PathBuf};

/// Export errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ExportError {
    /// Reading the recording.
    #[error(transparent)]
    Read(#[from] ReadError),
    /// Writing the output (or it exists and may not be replaced).
    #[error(transparent)]
    Write(#[from] RecordError),
    /// A selection that cannot be exported (named option, allowed values).
    #[error("{0}")]
    Selection(String),
}

/// Output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated values, one row per kept tick (or overview period), a header row of
    /// column names with units.
    Csv,
    /// NumPy `.npz`: one array per column (`time_s` float64, signals float32 as recorded,
    /// `overview.ticks` uint32), uncompressed.
    Npz,
}

/// What to export.
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The `/telemetry` columns.
    pub telemetry: bool,
    /// The `/truth` columns.
    pub truth: bool,
    /// The 1 kHz `/overview` columns (`.npz` only beside the others: another rate).
    pub overview: bool,
    /// First time kept, s from the run's start.
    pub from_s: f64,
    /// Last time kept, s from the run's start.
    pub to_s: f64,
    /// Keep every n-th tick of the window (1: all).
    pub every: u64,
}

impl Default for Selection {
    /// Telemetry and truth, every tick, the whole run.
    fn default() -> Self {
        Selection {
            telemetry: true,
            truth: true,
            overview: false,
            from_s: 0.0,
            to_s: f64::INFINITY,
            every: 1,
        }
    }
}

/// The storage type of a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    F64,
    F32,
    U32,
}

/// A column: name and type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct Column {
    pub name: String,
    pub kind: Kind,
}

/// The two tables a recording exports to: full-rate frames and the overview.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Table {
    Frames,
    Overview,
}

/// Where exported rows go.
pub(crate) trait Rows {
    /// One row of `table`, in the order of its columns.
    fn row(&mut self, table: Table, values: &[f64]) -> std::io::Result<()>;
    /// Completes the file and makes it durable.
    fn finish(self: Box<Self>) -> std::io::Result<()>;
}

impl Selection {
    fn check(&self, format: Format) -> Result<(), ExportError> {
        let bad = |m: String| Err(ExportError::Selection(m));
        if !(self.telemetry || self.truth || self.overview) {
            return bad("topics: nothing selected (allowed: telemetry, truth, overview)".into());
        }
        if !(self.from_s >= 0.0 && self.to_s > self.from_s) {
            return bad(format!(
                "from_s {} to_s {}: need 0 ≤ from < to (s)",
                self.from_s, self.to_s
            ));
        }
        if self.every == 0 {
            return bad("every: must be ≥ 1".into());
        }
        if format == Format::Csv && self.overview && (self.telemetry || self.truth) {
            return bad(
                "topics: the 1 kHz overview and the full-rate topics cannot share one CSV \
                 (export them separately, or to .npz)"
                    .into(),
            );
        }
        Ok(())
    }

    /// The columns of each selected table.
    pub(crate) fn columns(&self) -> Vec<(Table, Vec<Column>)> {
        let col = |name: String, kind| Column { name, kind };
        let mut out = Vec::new();
        if self.telemetry || self.truth {
            let mut c = vec![col("time_s".into(), Kind::F64)];
            if self.telemetry {
                c.extend(
                    TelemetryRecord::FIELDS
                        .iter()
                        .map(|f| col(format!("telemetry.{f}"), Kind::F32)),
                );
            }
            if self.truth {
                c.extend(
                    TruthRecord::FIELDS
                        .iter()
                        .map(|f| col(format!("truth.{f}"), Kind::F32)),
                );
            }
            out.push((Table::Frames, c));
        }
        if self.overview {
            let mut c = vec![
                col("overview.time_s".into(), Kind::F64),
                col("overview.ticks".into(), Kind::U32),
            ];
            for stat in ["min", "max", "mean"] {
                c.extend(
                    Signals::FIELDS
                        .iter()
                        .map(|f| col(format!("overview.{stat}.{f}"), Kind::F32)),
                );
            }
            out.push((Table::Overview, c));
        }
        out
    }

    fn keeps(&self, time_ns: u64) -> bool {
        let t = time_ns as f64 * 1e-9;
        t >= self.from_s && t <= self.to_s
    }
}

/// What an export wrote.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The file written.
    pub path: PathBuf,
    /// Full-rate rows (ticks) written.
    pub rows: u64,
    /// Overview rows written.
    pub overview_rows: u64,
    /// How the recording read (complete, unfinished, damaged).
    pub read: ReadReport,
}

/// Exports `input` to `output` as `format`, keeping what `selection` asks for.
pub fn export(
    input: &Path,
    output: &Path,
    format: Format,
    selection: &Selection,
    overwrite: Overwrite,
) -> Result<Exported, ExportError> {
    selection.check(format)?;
    crate::placement::check_target(output, overwrite)?;
    let columns = selection.columns();
    let partial = crate::placement::partial_path(output);
    let io = |source| RecordError::Io {
        path: output.to_owned(),
        source,
    };
    let result = (|| {
        let mut exporter = Exporter::new(selection, output);
        let mut rows: Box<dyn Rows> = match format {
            Format::Csv => Box::new(csv::CsvRows::create(&partial, &columns).map_err(io)?),
            Format::Npz => Box::new(npz::NpzRows::create(&partial, &columns).map_err(io)?),
        };
        let read = exporter.run(input, &mut *rows)?;
        rows.finish().map_err(io)?;
        crate::placement::publish(&partial, output, overwrite)?;
        Ok(Exported {
            path: output.to_owned(),
            rows: exporter.rows,
            overview_rows: exporter.overview_rows,
            read,
        })
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    result
}

/// Turns frames and overview messages into rows.
struct Exporter<'a> {
    selection: &'a Selection,
    output: &'a Path,
    tick: u64,
    rows: u64,
    overview_rows: u64,
    values: Vec<f64>,
    error: Option<std::io::Error>,
}

impl<'a> Exporter<'a> {
    fn new(selection: &'a Selection, output: &'a Path) -> Self {
        Exporter {
            selection,
            output,
            tick: 0,
            rows: 0,
            overview_rows: 0,
            values: Vec::with_capacity(64),
            error: None,
        }
    }

    fn run(&mut self, input: &Path, rows: &mut dyn Rows) -> Result<ReadReport, ExportError> {
        let mut visit = Feed {
            exporter: self,
            rows,
        };
        let read = stream(input, &mut visit)?;
        match self.error.take() {
            Some(source) => Err(RecordError::Io {
                path: self.output.to_owned(),
                source,
            }
            .into()),
            None => Ok(read),
        }
    }
}

/// The [`Visit`]or of an export.
struct Feed<'e, 'a> {
    exporter: &'e mut Exporter<'a>,
    rows: &'e mut dyn Rows,
}

impl Feed<'_, '_> {
    fn emit(&mut self, table: Table) {
        let e = &mut *self.exporter;
        if e.error.is_none() {
            if let Err(err) = self.rows.row(table, &e.values) {
                e.error = Some(err);
            }
        }
    }
}

impl Visit for Feed<'_, '_> {
    fn frame(&mut self, f: &Frame) {
        let e = &mut *self.exporter;
        let s = e.selection;
        if !(s.telemetry || s.truth) || !s.keeps(f.time_ns) {
            return;
        }
        e.tick += 1;
        if !(e.tick - 1).is_multiple_of(s.every) {
            return;
        }
        e.values.clear();
        e.values.push(f.time_ns as f64 * 1e-9);
        if s.telemetry {
            e.values.extend(f.telemetry.values().map(f64::from));
        }
        if s.truth {
            e.values.extend(f.truth.values().map(f64::from));
        }
        e.rows += 1;
        self.emit(Table::Frames);
    }

    fn message(&mut self, topic: &str, _sequence: u32, time_ns: u64, data: &[u8]) {
        let e = &mut *self.exporter;
        if topic != Overview::TOPIC || !e.selection.overview {
            return;
        }
        let Some(o) = Overview::decode(data).filter(|_| e.selection.keeps(time_ns)) else {
            return;
        };
        e.values.clear();
        e.values.push(time_ns as f64 * 1e-9);
        e.values.push(f64::from(o.ticks));
        for s in [o.min, o.max, o.mean] {
            e.values.extend(s.values().map(f64::from));
        }
        e.overview_rows += 1;
        self.emit(Table::Overview);
    }
}
