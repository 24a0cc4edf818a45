//! The files of a tool-path study: `toolpath.json` (the [`ToolpathStudy`]), `fts_table.csv`
//! (the FTS command table) and `part_error.csv` (the predicted error as a sag grid to load back
//! as `[compensation]`); their pictures are the `reports` crate's.

use super::ToolpathStudy;
use crate::report::{to_json, write_files, ReportError, Written};
use optics::toolpath::ToolPath;
use std::path::Path;

/// The FTS command table's size: radii (rows) × encoder counts (columns).
#[derive(Debug, Clone, Copy)]
pub struct TableSize {
    /// Radii from the aperture's edge to the axis.
    pub radii: usize,
    /// Encoder counts per revolution.
    pub counts: usize,
    /// The encoder's pulses per revolution.
    pub pulses_per_rev: u64,
}

/// Writes the study's data files into `dir`.
pub fn write_data(
    s: &ToolpathStudy,
    path: &ToolPath,
    table: TableSize,
    dir: &Path,
) -> Result<Written, ReportError> {
    let fts_table =
        super::demands::command_table(path, table.radii, table.counts, table.pulses_per_rev);
    write_files(
        dir,
        &[
            (
                "toolpath.json",
                &to_json(
                    "a prescription's tool path: the stage's demands per band, the predicted form error and the tool-setting sensitivities (servo toolpath)",
                    "report",
                    s,
                ),
            ),
            ("fts_table.csv", &fts_table),
            (
                "part_error.csv",
                &s.error_map
                    .to_sag_csv("predicted form error of the part (part − design)"),
            ),
        ],
    )
}
