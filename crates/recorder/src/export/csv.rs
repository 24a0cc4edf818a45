//! CSV rows: a header of column names (units in the names: `_m`, `_v`, `_s`), then one line
//! per row; floats printed with the digits that round-trip their stored precision.

use super::{Column, Kind, Rows, Table};
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

/// One CSV file (one table: a CSV holds one rate).
pub(crate) struct CsvRows {
    out: BufWriter<File>,
    kinds: Vec<Kind>,
}

impl CsvRows {
    pub(crate) fn create(path: &Path, tables: &[(Table, Vec<Column>)]) -> std::io::Result<Self> {
        let columns = &tables[0].1;
        let mut out = BufWriter::with_capacity(1 << 20, crate::placement::create_private(path)?);
        let names: Vec<&str> = columns.iter().map(|c| c.name.as_str()).collect();
        writeln!(out, "{}", names.join(","))?;
        Ok(CsvRows {
            out,
            kinds: columns.iter().map(|c| c.kind).collect(),
        })
    }
}

impl Rows for CsvRows {
    fn row(&mut self, _table: Table, values: &[f64]) -> std::io::Result<()> {
        for (i, (&v, kind)) in values.iter().zip(&self.kinds).enumerate() {
            if i > 0 {
                self.out.write_all(b",")?;
            }
            match kind {
                Kind::F64 => write!(self.out, "{v}")?,
                Kind::F32 => write!(self.out, "{:e}", v as f32)?,
                Kind::U32 => write!(self.out, "{}", v as u32)?,
            }
        }
        self.out.write_all(b"\n")
    }

    fn finish(mut self: Box<Self>) -> std::io::Result<()> {
        self.out.flush()?;
        self.out.get_ref().sync_data()
    }
}
