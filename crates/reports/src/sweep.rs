//! `sweep.csv`, `sweep.json` and the bandwidth-sweep plot (Fig 5-14).

use crate::plot::{Figure, Series};
use crate::plot_files;
use std::fmt::Write as _;
use std::path::Path;
use studies::report::{data, ReportError, Written};
use studies::sweep::Sweep;

/// `sweep.csv`, `sweep.json`, `sweep.{png,svg}` (thesis Fig 5-14).
pub fn write(sweeps: &[Sweep], dir: &Path) -> Result<Written, ReportError> {
    let mut csv = String::from("label,target_hz,bandwidth_hz,kp,ki_per_s,kd_s,gain_scale,predicted_following_m,predicted_true_m,simulated_following_m,simulated_true_m\n");
    for s in sweeps {
        for p in &s.points {
            let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.6e}"));
            writeln!(
                csv,
                "{},{:.1},{:.3},{:.6e},{:.6e},{:.6e},{:.6},{:.6e},{:.6e},{},{}",
                s.label,
                p.target_hz,
                p.bandwidth_hz,
                p.pid.kp,
                p.pid.ki,
                p.pid.kd,
                p.gain_scale,
                p.predicted_following_m,
                p.predicted_true_m,
                opt(p.simulated_following_m),
                opt(p.simulated_true_m)
            )
            .unwrap();
        }
    }
    let mut out = data(
        dir,
        "sweep",
        "RMS errors against closed-loop bandwidth, thesis Fig 5-14 (servo budget --sweep)",
        &csv,
        sweeps,
    )?;
    let mut series = Vec::new();
    for s in sweeps {
        let bw: Vec<f64> = s.points.iter().map(|p| p.bandwidth_hz).collect();
        let nm = |f: fn(&studies::sweep::SweepPoint) -> Option<f64>| {
            s.points
                .iter()
                .map(|p| f(p).map_or(f64::NAN, |v| v * 1e9))
                .collect::<Vec<f64>>()
        };
        series.push(Series::line(
            format!("{} following, predicted", s.label),
            bw.clone(),
            nm(|p| Some(p.predicted_following_m)),
        ));
        series.push(Series::line(
            format!("{} true, predicted", s.label),
            bw.clone(),
            nm(|p| Some(p.predicted_true_m)),
        ));
        if s.points.iter().any(|p| p.simulated_following_m.is_some()) {
            series.push(Series {
                label: format!("{} following, simulated", s.label),
                x: bw.clone(),
                y: nm(|p| p.simulated_following_m),
                points: true,
            });
            series.push(Series {
                label: format!("{} true, simulated", s.label),
                x: bw,
                y: nm(|p| p.simulated_true_m),
                points: true,
            });
        }
    }
    let fig = Figure {
        title: "RMS error against closed-loop bandwidth (thesis Fig 5-14)".into(),
        x_label: "closed-loop −3 dB bandwidth (Hz)".into(),
        y_label: "RMS error (nm)".into(),
        // Linear, as Fig 5-14: the sweep spans about a decade, where a log axis has two labels.
        log_x: false,
        log_y: false,
        series,
    };
    out.note = plot_files(&[(fig, "sweep")], dir, &mut out.files);
    Ok(out)
}
