//! `toolpath.json` (the [`ToolpathStudy`](super::ToolpathStudy)), `fts_table.csv` (the FTS
//! command table), `part_error.csv` (the predicted error as a sag grid to load back as
//! `[compensation]`), and the pictures `fts_path`, `predicted_form_error` and `bands`.

use super::{ApertureMap, ToolpathStudy};
use crate::plot::{self, Figure, Map, Series, SquareMap};
use crate::report::{plots, to_json, write_files, ReportError, Written};
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

/// The square picture of `map` (values in nm).
fn picture(map: &ApertureMap, title: String, value_label: &str) -> SquareMap {
    let n = map.nodes;
    let half = map.pitch_m * (n as f64) / 2.0 * 1e3;
    // Rows bottom up for the picture.
    let values = (0..n)
        .rev()
        .flat_map(|r| map.values[r * n..(r + 1) * n].iter().map(|v| v * 1e9))
        .collect();
    SquareMap(Map {
        title,
        x_label: "x (mm)".into(),
        y_label: "y (mm)".into(),
        x: (-half, half),
        y: (-half, half),
        cols: n,
        values,
        value_label: value_label.into(),
    })
}

/// Writes the study's files into `dir`.
pub fn write(
    s: &ToolpathStudy,
    path: &ToolPath,
    table: TableSize,
    title: &str,
    dir: &Path,
) -> Result<Written, ReportError> {
    let fts_table =
        runner::toolpath::command_table(path, table.radii, table.counts, table.pulses_per_rev);
    let mut out = write_files(
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
    )?;
    let f = &s.feasibility;
    let mm: Vec<f64> = f
        .bands
        .iter()
        .map(|b| 0.5 * (b.radius_m[0] + b.radius_m[1]) * 1e3)
        .collect();
    let col = |g: fn(&runner::toolpath::Band) -> f64| f.bands.iter().map(g).collect::<Vec<_>>();
    let bands = Figure {
        title: format!("What the path asks of the stage, per radius band — {title}"),
        x_label: "band centre radius (mm)".into(),
        y_label: "µm, nm, V (see legend)".into(),
        log_x: false,
        log_y: true,
        series: vec![
            Series::line("FTS stroke (µm)", mm.clone(), col(|b| b.stroke_m * 1e6)),
            Series::line(
                "predicted tool error RMS (nm)",
                mm.clone(),
                col(|b| b.predicted_rms_m * 1e9),
            ),
            Series::line("peak DAC command (V)", mm, col(|b| b.peak_voltage_v)),
        ],
    };
    out.note = plots(&[(bands, "bands")], dir, &mut out.files);
    let fts = picture(
        &s.fts_map,
        "FTS path: the tool path less the Z slide's symmetric part".into(),
        "FTS height (nm)",
    );
    let tr = s.form.tilt_removed;
    let error = picture(
        &s.error_map,
        format!(
            "Predicted form error: {:.1} nm PV, {:.2} nm RMS (piston, tilt removed)",
            tr.pv_m * 1e9,
            tr.rms_m * 1e9
        ),
        "form error (nm)",
    );
    for (item, stem) in [(fts, "fts_path"), (error, "predicted_form_error")] {
        if out.note.is_some() {
            break;
        }
        match plot::write(&item, &dir.join(stem)) {
            Ok(paths) => out.files.extend(paths),
            Err(e) => out.note = Some(e.to_string()),
        }
    }
    Ok(out)
}
