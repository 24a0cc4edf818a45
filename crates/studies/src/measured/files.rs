//! The files of a registered measurement: `registration.json` (the [`MeasuredStudy`]),
//! `residual.csv` (the residual on the instrument's grid, nm) and `part_error.csv` (the
//! residual in the part's frame as a sag grid, what `servo compensate` takes); a compensation
//! cycle's `compensation.json` and `compensation.csv`.

use super::compensate::NextCompensation;
use super::MeasuredStudy;
use crate::report::{to_json, write_files, ReportError, Written};
use std::path::Path;

/// The residual on the instrument's grid as a CSV of heights in nm (empty cells: no data).
fn residual_csv(s: &MeasuredStudy) -> String {
    let m = &s.registration.residual_map;
    let mut out = format!(
        "# registered residual (measured − fitted design) heights in nm, row 0 at +y, column 0 at -x, pitch {} mm\n",
        m.pitch_m[0] * 1e3
    );
    for row in m.heights_m.chunks(m.cols) {
        let cells: Vec<String> = row
            .iter()
            .map(|v| {
                if v.is_finite() {
                    format!("{:.4}", v * 1e9)
                } else {
                    String::new()
                }
            })
            .collect();
        out += &cells.join(",");
        out.push('\n');
    }
    out
}

/// Writes the study's data files into `dir`.
pub fn write_data(s: &MeasuredStudy, dir: &Path) -> Result<Written, ReportError> {
    write_files(
        dir,
        &[
            (
                "registration.json",
                &to_json(
                    "a measured map registered against its design: pose, setting errors, residual form (servo register)",
                    "report",
                    s,
                ),
            ),
            ("residual.csv", &residual_csv(s)),
            (
                "part_error.csv",
                &s.part_map
                    .to_sag_csv("registered residual of the measured part (part − design)"),
            ),
        ],
    )
}

/// Writes a compensation cycle's data into `dir`: `compensation.json` and, when the tool path
/// with it stays within the stage (`write_grid`), `compensation.csv` (the sag grid a
/// prescription's `[compensation]` loads).
pub fn write_compensation(
    s: &NextCompensation,
    write_grid: bool,
    dir: &Path,
) -> Result<Written, ReportError> {
    let json = to_json(
        "the next cut's compensation from a registered residual, and the tool path with it (servo compensate)",
        "report",
        s,
    );
    let grid = s
        .next_map
        .to_sag_csv("next compensation: the part's error to subtract (part − design)");
    let mut files = vec![("compensation.json", json.as_str())];
    if write_grid {
        files.push(("compensation.csv", grid.as_str()));
    }
    write_files(dir, &files)
}
