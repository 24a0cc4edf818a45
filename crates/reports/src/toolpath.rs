//! What a tool-path study writes: its data (`studies::toolpath::write_data`) and the pictures
//! `fts_path`, `predicted_form_error` and `bands`.

use crate::plot::{Figure, Map, Series, SquareMap};
use crate::{plot_file, plot_files};
use optics::toolpath::ToolPath;
use std::path::Path;
use studies::report::{ReportError, Written};
use studies::toolpath::{write_data, ApertureMap, TableSize, ToolpathStudy};

/// The square picture of `map` (values in nm).
pub(crate) fn picture(map: &ApertureMap, title: String, value_label: &str) -> SquareMap {
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

/// Writes the study's files into `dir`: its data and its pictures.
pub fn write(
    s: &ToolpathStudy,
    path: &ToolPath,
    table: TableSize,
    title: &str,
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut out = write_data(s, path, table, dir)?;
    let f = &s.feasibility;
    let mm: Vec<f64> = f
        .bands
        .iter()
        .map(|b| 0.5 * (b.radius_m[0] + b.radius_m[1]) * 1e3)
        .collect();
    let col =
        |g: fn(&studies::toolpath::demands::Band) -> f64| f.bands.iter().map(g).collect::<Vec<_>>();
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
    out.note = plot_files(&[(bands, "bands")], dir, &mut out.files);
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
        out.note = out
            .note
            .take()
            .or_else(|| plot_file(&item, &dir.join(stem), &mut out.files));
    }
    Ok(out)
}
