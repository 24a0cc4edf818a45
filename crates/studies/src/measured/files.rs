//! The files of a registered measurement: `registration.json` (the [`MeasuredStudy`]),
//! `residual.csv` (the residual on the instrument's grid, nm) and `part_error.csv` (the
//! residual in the part's frame as a sag grid, what `servo compensate` takes).

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
