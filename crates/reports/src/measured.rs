//! What a registered measurement writes: its data (`studies::measured::write_data`) and the
//! pictures `measured_residual` (on the instrument's grid) and `part_residual` (in the part's
//! frame, what the next compensation is made from).

use crate::plot::{Map, SquareMap};
use crate::plot_file;
use crate::toolpath::picture;
use std::path::Path;
use studies::measured::compensate::NextCompensation;
use studies::measured::{write_compensation, write_data, MeasuredStudy};
use studies::report::{ReportError, Written};

/// Writes the study's files into `dir`: its data and its pictures.
pub fn write(s: &MeasuredStudy, dir: &Path) -> Result<Written, ReportError> {
    let mut out = write_data(s, dir)?;
    let m = &s.registration.residual_map;
    let (hx, hy) = (
        m.pitch_m[0] * m.cols as f64 / 2.0 * 1e3,
        m.pitch_m[1] * m.rows as f64 / 2.0 * 1e3,
    );
    let r = &s.registration.residual.tilt_removed;
    let measured = Map {
        title: format!(
            "Measured residual after registration: {:.1} nm PV, {:.2} nm RMS ({} of {} pixels on the part)",
            r.pv_m * 1e9,
            r.rms_m * 1e9,
            s.registration.pixels_on_part,
            m.rows * m.cols
        ),
        x_label: "instrument x (mm)".into(),
        y_label: "instrument y (mm)".into(),
        x: (-hx, hx),
        y: (-hy, hy),
        cols: m.cols,
        // Rows bottom up for the picture.
        values: m
            .heights_m
            .chunks(m.cols)
            .rev()
            .flatten()
            .map(|v| v * 1e9)
            .collect(),
        value_label: "residual (nm)".into(),
    };
    let part = picture(
        &s.part_map,
        "Residual in the part's frame (the next compensation's input)".into(),
        "residual (nm)",
    );
    out.note = plot_file(
        &SquareMap(measured),
        &dir.join("measured_residual"),
        &mut out.files,
    );
    out.note = out
        .note
        .take()
        .or_else(|| plot_file(&part, &dir.join("part_residual"), &mut out.files));
    Ok(out)
}

/// Writes a compensation cycle's files into `dir` (the grid only when `write_grid`) and the
/// picture `compensation`.
pub fn write_cycle(
    s: &NextCompensation,
    write_grid: bool,
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut out = write_compensation(s, write_grid, dir)?;
    let t = s.next.tilt_removed;
    let map = picture(
        &s.next_map,
        format!(
            "Next compensation (part − design to subtract): {:.1} nm PV, {:.2} nm RMS after piston and tilt",
            t.pv_m * 1e9,
            t.rms_m * 1e9
        ),
        "compensation (nm)",
    );
    out.note = plot_file(&map, &dir.join("compensation"), &mut out.files);
    Ok(out)
}
