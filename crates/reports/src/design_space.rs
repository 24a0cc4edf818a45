//! What a finished design-space study writes: its data (`studies::design_space::write_data`)
//! and the plots — the errors and bandwidth along a one-parameter study (thesis Fig 6-14), a
//! map of the objective over a two-parameter grid with its optimum marked (Fig 6-17), the
//! sensitivities at the operating point.

use crate::plot::{Bars, Contour, Figure, Series, Stacked};
use crate::plot_file;
use loop_model::closed_loop::SOURCES;
use std::path::Path;
use studies::design_space::evaluate::Point;
use studies::design_space::sensitivity::Sensitivity;
use studies::design_space::spec::{Family, Objective, Sampling, Spacing, Study};
use studies::design_space::{axis_label, objective, optima, Findings};
use studies::report::Written;

/// Adds the plots of a finished study (its data written into `dir` as `out` by
/// [`studies::design_space::finish`]) to `dir` and `out`.
pub fn plots(study: &Study, points: &[Point], findings: &Findings, dir: &Path, out: &mut Written) {
    let t = &study.table;
    let sensitivities = &findings.sensitivities;
    let files = &mut out.files;
    let mut notes = Vec::new();
    if t.parameters.len() == 1 {
        notes.push(plot_file(&curves(study, points), &dir.join("study"), files));
    }
    if t.parameters.len() == 2 && t.sampling == Sampling::Grid {
        for &family in &t.controllers {
            let stem = dir.join(format!("map-{}", family.name()));
            notes.push(plot_file(&map(study, points, family), &stem, files));
        }
    }
    if !sensitivities.is_empty() {
        notes.push(plot_file(
            &bars(sensitivities),
            &dir.join("sensitivity"),
            files,
        ));
    }
    out.note = notes.into_iter().flatten().next();
}

/// Fig 6-14: RMS errors (top) and bandwidth (bottom) along the study's one parameter, one
/// curve per family; failed points leave gaps.
fn curves(study: &Study, points: &[Point]) -> Stacked {
    let p = &study.table.parameters[0];
    let log_x = p.spacing == Spacing::Log;
    // Each family's following error and bandwidth share a colour (same index in both charts);
    // the true errors follow.
    let (mut following, mut truth, mut bandwidths) = (Vec::new(), Vec::new(), Vec::new());
    for &family in &study.table.controllers {
        let mut rows: Vec<&Point> = points.iter().filter(|q| q.family == family).collect();
        rows.sort_by(|a, b| a.values[0].total_cmp(&b.values[0]));
        let x: Vec<f64> = rows.iter().map(|q| q.values[0]).collect();
        let get = |f: fn(&studies::design_space::evaluate::Metrics) -> f64| -> Vec<f64> {
            rows.iter()
                .map(|q| q.outcome.as_ref().map_or(f64::NAN, f))
                .collect()
        };
        let name = family_label(study, family);
        following.push(Series::line(
            format!("{name}: following error (its bandwidth below)"),
            x.clone(),
            get(|m| m.following_rms_m * 1e9),
        ));
        truth.push(Series::line(
            format!("{name}: true error"),
            x.clone(),
            get(|m| m.true_rms_m * 1e9),
        ));
        bandwidths.push(Series::line(
            format!("{name}: bandwidth"),
            x,
            get(|m| m.bandwidth_hz),
        ));
    }
    let mut errors = following;
    errors.extend(truth);
    let x_label = axis_label(&p.key);
    Stacked {
        title: format!(
            "{}: achievable RMS error and −3 dB bandwidth against {} (thesis Fig 6-14)",
            study.table.name, x_label
        ),
        top: Figure {
            title: String::new(),
            x_label: x_label.clone(),
            y_label: "RMS error (nm)".into(),
            log_x,
            log_y: false,
            series: errors,
        },
        bottom: Figure {
            title: String::new(),
            x_label,
            y_label: "−3 dB bandwidth (Hz)".into(),
            log_x,
            log_y: false,
            series: bandwidths,
        },
    }
}

fn family_label(study: &Study, family: Family) -> String {
    match family {
        Family::H2 => "H2-optimal".into(),
        Family::H2Bandwidth => format!("H2 at {} Hz", study.table.bandwidth_hz),
        Family::Pid => format!("PID at {} Hz", study.table.bandwidth_hz),
    }
}

/// Fig 6-17: the objective over the two parameters of a grid, the optimum marked.
fn map(study: &Study, points: &[Point], family: Family) -> Contour {
    let t = &study.table;
    let grid = |j: usize| -> Vec<f64> {
        let mut v: Vec<f64> = points
            .iter()
            .filter(|p| p.family == family)
            .map(|p| p.values[j])
            .collect();
        v.sort_by(f64::total_cmp);
        v.dedup();
        v
    };
    let (x, y) = (grid(0), grid(1));
    let mut values = vec![f64::NAN; x.len() * y.len()];
    for p in points.iter().filter(|p| p.family == family) {
        let c = x.partition_point(|&v| v < p.values[0]);
        let r = y.partition_point(|&v| v < p.values[1]);
        values[r * x.len() + c] = objective(study, p) * 1e9;
    }
    let what = match t.objective {
        Objective::Following => "RMS following error",
        Objective::True => "RMS true error",
    };
    let mark = optima(study, points)
        .into_iter()
        .find(|o| o.controller == family)
        .map(|o| {
            let value = objective(
                study,
                &points[points.partition_point(|p| p.index < o.index)],
            );
            (
                o.values[0].1,
                o.values[1].1,
                format!(
                    "optimum {:.3} nm at {} = {:.4e}, {} = {:.4e} ({:.0} Hz)",
                    value * 1e9,
                    axis_label(&o.values[0].0),
                    o.values[0].1,
                    axis_label(&o.values[1].0),
                    o.values[1].1,
                    o.bandwidth_hz
                ),
            )
        });
    Contour {
        title: format!(
            "{}: {what}, {} (thesis Fig 6-17)",
            t.name,
            family_label(study, family)
        ),
        x_label: axis_label(&t.parameters[0].key),
        y_label: axis_label(&t.parameters[1].key),
        value_label: format!("{what} (nm)"),
        log_x: t.parameters[0].spacing == Spacing::Log,
        log_y: t.parameters[1].spacing == Spacing::Log,
        x,
        y,
        values,
        mark,
    }
}

/// The sensitivities as bars: one row per family and parameter, one bar for each total and for
/// each source's share of the true error (sources that contribute nothing have no bar).
fn bars(s: &[Sensitivity]) -> Bars {
    let mut groups = vec![
        "following error, total".to_owned(),
        "true error, total".to_owned(),
    ];
    let mut values = vec![
        s.iter().map(|e| e.following).collect::<Vec<_>>(),
        s.iter().map(|e| e.true_error).collect(),
    ];
    for (k, (name, _)) in SOURCES.iter().enumerate() {
        let v: Vec<f64> = s.iter().map(|e| e.true_by_source[k]).collect();
        if v.iter().any(|x| x.is_finite()) {
            groups.push(format!("true error from {name}"));
            values.push(v);
        }
    }
    Bars {
        title:
            "Sensitivity at the operating point: % change of RMS error per % change of parameter"
                .into(),
        value_label: "d ln(RMS error) / d ln(parameter)".into(),
        rows: s
            .iter()
            .map(|e| format!("{} ({})", axis_label(&e.key), e.controller.name()))
            .collect(),
        groups,
        values,
    }
}
