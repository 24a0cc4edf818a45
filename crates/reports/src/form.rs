//! `machine.json`, `form_map.csv`, `trajectory.csv`, `roughness_profile.csv`, the form-error map,
//! the trajectory plots and the machined face's radial profile of a machining run.

use crate::plot::{self, Figure, Series};
use crate::{plot_file, plot_files};
use std::fmt::Write as _;
use std::path::Path;
use studies::form::MAP_COLUMNS;
use studies::report::{to_json, write_files, ReportError, Written};

/// Picture columns of the form-error map (the data keep every 0.1° bin).
const MAP_PICTURE_COLUMNS: usize = 720;

/// `machine.json` (the [`FormReport`](studies::form::FormReport)), `form_map.csv`,
/// `trajectory.csv`, and the pictures `form_error_map`, `trajectory`, `trajectory_error`
/// (PNG + SVG).
pub fn write(
    a: &studies::form::FormAnalysis,
    title: &str,
    learned: Option<&[f64]>,
    dir: &Path,
) -> Result<Written, ReportError> {
    let report = a.report();
    let (rows, values) = a.map();
    let [inner, outer] = report.band_m;
    let ring = (outer - inner) / report.revolutions.max(1e-9);
    let mut map_csv = String::from("revolution,radius_m,angle_deg,form_error_m\n");
    for (i, v) in values.iter().enumerate().filter(|(_, v)| v.is_finite()) {
        let (r, c) = (i / MAP_COLUMNS, i % MAP_COLUMNS);
        let angle = (c as f64 + 0.5) * 360.0 / MAP_COLUMNS as f64;
        let radius = outer - ring * (r as f64 + (c as f64 + 0.5) / MAP_COLUMNS as f64);
        writeln!(map_csv, "{r},{radius:.9e},{angle:.2},{v:.6e}").unwrap();
    }
    let mut seg_csv = String::from("time_s,reference_m,tool_m,measured_m,cutting_force_n\n");
    for s in a.segment() {
        writeln!(
            seg_csv,
            "{:.9},{:.6e},{:.6e},{:.6e},{:.6e}",
            s.time_s, s.reference_m, s.tool_m, s.measured_m, s.cutting_force_n
        )
        .unwrap();
    }
    let mut out = write_files(
        dir,
        &[
            ("form_map.csv", &map_csv),
            ("machine.json", &to_json("form error, grid amplitude and roughness of a machined surface (servo machine)", "report", &report)),
            ("trajectory.csv", &seg_csv),
        ],
    )?;
    // The map picture: rows = revolutions (outermost at the top), columns merged to 0.5°.
    let merge = MAP_COLUMNS / MAP_PICTURE_COLUMNS;
    let picture: Vec<f64> = (0..rows)
        .rev()
        .flat_map(|r| {
            let row = &values[r * MAP_COLUMNS..(r + 1) * MAP_COLUMNS];
            row.chunks(merge)
                .map(|c| {
                    let (s, n) = c
                        .iter()
                        .filter(|v| v.is_finite())
                        .fold((0.0, 0), |(s, n), v| (s + v * 1e9, n + 1));
                    if n > 0 {
                        s / n as f64
                    } else {
                        f64::NAN
                    }
                })
                .collect::<Vec<f64>>()
        })
        .collect();
    // Mean-removed, as the summary's RMS: the piston (the shank's static compression under the
    // cutting force) would otherwise fill the map with one colour and hide the form.
    let mean_nm = report.form_error_m.mean * 1e9;
    let picture: Vec<f64> = picture.into_iter().map(|v| v - mean_nm).collect();
    let map = plot::Map {
        title: format!("Form error, tool − design, mean {mean_nm:.1} nm removed — {title}"),
        x_label: "spindle angle (°)".into(),
        y_label: "radius (mm)".into(),
        x: (0.0, 360.0),
        y: ((outer - ring * rows as f64) * 1e3, outer * 1e3),
        cols: MAP_PICTURE_COLUMNS,
        values: picture,
        value_label: "form error − mean (nm)".into(),
    };
    let ms: Vec<f64> = a.segment().iter().map(|s| s.time_s * 1e3).collect();
    let um = |f: fn(&studies::form::SegmentRow) -> f64| -> Vec<f64> {
        a.segment().iter().map(|s| f(s) * 1e6).collect()
    };
    let nm = |f: fn(&studies::form::SegmentRow) -> f64| -> Vec<f64> {
        a.segment().iter().map(|s| f(s) * 1e9).collect()
    };
    let series = |label: &str, y: Vec<f64>| Series::line(label, ms.clone(), y);
    let trajectory = Figure {
        title: format!("Tool trajectory (thesis Figs 8-15, 8-20) — {title}"),
        x_label: "time (ms)".into(),
        y_label: "height (µm)".into(),
        log_x: false,
        log_y: false,
        series: vec![
            series("command (design surface)", um(|s| s.reference_m)),
            series("true tool", um(|s| s.tool_m)),
        ],
    };
    let errors = Figure {
        title: format!("Tool errors along the segment — {title}"),
        x_label: "time (ms)".into(),
        y_label: "error (nm)".into(),
        log_x: false,
        log_y: false,
        series: vec![
            series("true tool − command", nm(|s| s.tool_m - s.reference_m)),
            series(
                "measured − command (the sensor's view)",
                nm(|s| s.measured_m - s.reference_m),
            ),
        ],
    };
    let mut figures = vec![(trajectory, "trajectory"), (errors, "trajectory_error")];
    if let Some(profile) = a.roughness_profile() {
        let mut csv = String::from("radius_m,machined_m,feed_marks_m,servo_motion_m\n");
        for r in &profile {
            writeln!(csv, "{:.9e},{:.6e},{:.6e},{:.6e}", r[0], r[1], r[2], r[3]).unwrap();
        }
        out.files.push(studies::report::write_file(
            dir.join("roughness_profile.csv"),
            &csv,
        )?);
        let mid = profile[profile.len() / 2][0];
        let um: Vec<f64> = profile.iter().map(|r| (r[0] - mid) * 1e6).collect();
        let nm = |k: usize| profile.iter().map(|r| r[k] * 1e9).collect();
        figures.push((
            Figure {
                title: "Machined face across ten feed marks (§8.5.1)".into(),
                x_label: format!("radius − {:.3} mm (µm)", mid * 1e3),
                y_label: "height (nm)".into(),
                log_x: false,
                log_y: false,
                series: vec![
                    Series::line("machined surface", um.clone(), nm(1)),
                    Series::line("feed marks alone (still tool)", um.clone(), nm(2)),
                    Series::line("servo motion alone (nearest pass)", um, nm(3)),
                ],
            },
            "roughness_profile",
        ));
    }
    if let Some(table) = learned {
        out.files.push(studies::report::write_file(
            dir.join("repetitive_table.csv"),
            &runner::repetitive::table_csv(table),
        )?);
        figures.extend(repetitive_figures(&report, table, title));
    }
    out.note = plot_files(&figures, dir, &mut out.files)
        .or_else(|| plot_file(&map, &dir.join("form_error_map"), &mut out.files));
    Ok(out)
}

/// The repetitive controller's convergence (form error RMS per revolution) and its learned
/// correction over one revolution.
fn repetitive_figures(
    report: &studies::form::FormReport,
    table: &[f64],
    title: &str,
) -> [(Figure, &'static str); 2] {
    let revs: Vec<f64> = (1..=report.revolution_rms_m.len())
        .map(|r| r as f64)
        .collect();
    let rms: Vec<f64> = report.revolution_rms_m.iter().map(|v| v * 1e9).collect();
    // The first twentieth of the revolution: a whole one is as dense as the surface.
    let n = table.len() as f64;
    let shown = table.len().div_ceil(20);
    let deg: Vec<f64> = (0..shown).map(|i| (i as f64 + 0.5) * 360.0 / n).collect();
    let nm: Vec<f64> = table[..shown].iter().map(|v| v * 1e9).collect();
    [
        (
            Figure {
                title: format!("Form error RMS per revolution — {title}"),
                x_label: "revolution".into(),
                y_label: "form error RMS (nm)".into(),
                log_x: false,
                log_y: true,
                series: vec![Series::line("form error RMS of the revolution", revs, rms)],
            },
            "repetitive_convergence",
        ),
        (
            Figure {
                title: format!("Learned correction at the end of the run, 0–18° — {title}"),
                x_label: "spindle angle (°)".into(),
                y_label: "correction added to the reference (nm)".into(),
                log_x: false,
                log_y: false,
                series: vec![Series::line("repetitive table", deg, nm)],
            },
            "repetitive_table",
        ),
    ]
}
