//! The files of a tool-path study: `toolpath.json` (the [`ToolpathStudy`]), `fts_table.csv`
//! (the FTS command table) and `part_error.csv` (the predicted error as a sag grid to load back
//! as `[compensation]`); their pictures are the `reports` crate's.

use super::{ApertureMap, ToolpathStudy};
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

/// `map` as a sag grid in mm (Zemax's layout: row 0 at +y, column 0 at −x), the sag being
/// `−map` (the map is a height toward the tool); nodes outside the aperture take the value of
/// the nearest inside along their radius, so the grid's interpolation has neighbours there.
fn sag_grid_csv(map: &ApertureMap) -> String {
    let n = map.nodes;
    let half = (n - 1) as f64 / 2.0;
    let mut s = format!(
        "# predicted form error of the part as sag (part − design) in mm, row 0 at +y, column 0 at -x, pitch {} mm\n",
        map.pitch_m * 1e3
    );
    for row in 0..n {
        let cells: Vec<String> = (0..n)
            .map(|col| {
                let mut v = map.values[row * n + col];
                // Walk inward along the radius to the aperture.
                let (x, y) = (col as f64 - half, half - row as f64);
                let mut f = 1.0;
                while !v.is_finite() && f > 0.0 {
                    f -= 1.0 / half;
                    let (c, r) = (
                        (x * f + half).round() as usize,
                        (half - y * f).round() as usize,
                    );
                    v = map.values[r.min(n - 1) * n + c.min(n - 1)];
                }
                format!("{:.6e}", if v.is_finite() { -v * 1e3 } else { 0.0 })
            })
            .collect();
        s += &cells.join(",");
        s.push('\n');
    }
    s
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
            ("part_error.csv", &sag_grid_csv(&s.error_map)),
        ],
    )
}
