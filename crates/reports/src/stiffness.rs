//! `stiffness.csv`, `stiffness.json` and the compliance plot (eq 7-9).

use crate::plot::{Figure, Series};
use crate::plot_files;
use std::fmt::Write as _;
use std::path::Path;
use studies::report::{data, ReportError, Written};

/// `stiffness.csv`, `stiffness.json`, `compliance.{png,svg}` (thesis Fig 7-7, 7-14).
pub fn write(
    curves: &[studies::stiffness::ComplianceCurve],
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut csv = String::from(
        "ka,pid_scale,stable,freq_hz,analytic_m_per_n,sampled_m_per_n,sampled_m2_m_per_n\n",
    );
    for c in curves {
        for i in 0..c.freq_hz.len() {
            writeln!(
                csv,
                "{},{:.6},{},{:.6},{:.6e},{:.6e},{:.6e}",
                c.ka,
                c.pid_scale,
                c.stable(),
                c.freq_hz[i],
                c.analytic_m_per_n[i],
                c.sampled_m_per_n[i],
                c.sampled_m2_m_per_n[i]
            )
            .unwrap();
        }
    }
    let mut out = data(
        dir,
        "stiffness",
        "dynamic compliance at the tool, thesis eq 7-9 (servo stiffness)",
        &csv,
        curves,
    )?;
    let mut series = Vec::new();
    for c in curves.iter().filter(|c| c.stable()) {
        let um = |v: &Vec<f64>| v.iter().map(|x| x * 1e6).collect::<Vec<f64>>();
        series.push(Series::line(
            format!("Ka {} analytic (eq 7-9)", c.ka),
            c.freq_hz.clone(),
            um(&c.analytic_m_per_n),
        ));
        series.push(Series {
            label: format!("Ka {} sampled loop", c.ka),
            x: c.freq_hz.clone(),
            y: um(&c.sampled_m_per_n),
            points: true,
        });
    }
    let fig = Figure {
        title: "Dynamic compliance X/dF at the tool (thesis eq 7-9, Fig 7-7)".into(),
        x_label: "frequency (Hz)".into(),
        y_label: "|X/dF| (µm/N)".into(),
        log_x: true,
        log_y: true,
        series,
    };
    out.note = plot_files(&[(fig, "compliance")], dir, &mut out.files);
    Ok(out)
}
