//! `frf.csv`, `frf.json` and the Bode plot of a measured FRF beside its model.

use crate::plot::{self, Figure, Series};
use crate::plot_file;
use std::fmt::Write as _;
use std::path::Path;
use studies::report::{data, ReportError, Written};

/// What an FRF was measured for and on: the quantity, the configured plant and rate (the
/// model beside it), and the plant that answered (the simulator in this process, or the one
/// serving a prefix).
#[derive(Debug, Clone, Copy)]
pub struct Provenance<'a> {
    /// Which loop, hence which quantity.
    pub which: studies::frf::FrfLoop,
    /// The configured plant and rate.
    pub made_for: &'a run_config::MadeFor,
    /// Where it was measured (`the simulated stage, seed 1`, `the plant serving fts-servo/lab`).
    pub measured_on: &'a str,
}

/// The comment line that opens `frf.csv`: which quantity, in which unit, made for which plant,
/// measured on which (`servo identify` reads the quantity and refuses anything but P).
fn provenance_line(p: &Provenance) -> String {
    format!(
        "# fts-servo frf: quantity = {} ({}); unit m/V; made for {}; measured on {}; {}\n",
        p.which.quantity(),
        p.which.describe(),
        p.made_for.describe(),
        p.measured_on,
        p.made_for.tool
    )
}

/// What `frf.json` holds: the quantity, its unit, what it was measured on, the points.
#[derive(serde::Serialize)]
struct FrfFile<'a> {
    quantity: &'static str,
    description: &'static str,
    unit: &'static str,
    made_for: &'a run_config::MadeFor,
    measured_on: &'a str,
    points: &'a [studies::frf::FrfPoint],
}

/// `frf.csv` (opened by a comment line naming the quantity, its unit and plant), `frf.json`
/// (the same as fields), `bode.{png,svg}` (magnitude above phase).
pub fn write(
    points: &[studies::frf::FrfPoint],
    model: &[(f64, num_complex::Complex64)],
    title: &str,
    provenance: &Provenance,
    dir: &Path,
) -> Result<Written, ReportError> {
    let Provenance {
        which,
        made_for,
        measured_on,
    } = *provenance;
    let mut csv = provenance_line(provenance);
    csv.push_str("freq_hz,magnitude_m_per_v,phase_deg,coherence,uncertainty_m_per_v,model_magnitude_m_per_v,model_phase_deg,clipped,excitation_v,accel_magnitude_v_per_v,accel_phase_deg,accel_uncertainty_v_per_v\n");
    for p in points {
        writeln!(
            csv,
            "{:.6},{:.6e},{:.4},{:.6},{:.3e},{:.6e},{:.4},{},{:.6e},{:.6e},{:.4},{:.3e}",
            p.freq_hz,
            p.magnitude,
            p.phase_deg,
            p.coherence,
            p.uncertainty,
            p.model_magnitude,
            p.model_phase_deg,
            p.clipped,
            p.excitation_v,
            p.accel_magnitude,
            p.accel_phase_deg,
            p.accel_uncertainty
        )
        .unwrap();
    }
    let file = FrfFile {
        quantity: which.quantity(),
        description: which.describe(),
        unit: "m/V",
        made_for,
        measured_on,
        points,
    };
    let mut out = data(
        dir,
        "frf",
        "frequency response, measured beside the model (servo frf)",
        &csv,
        &file,
    )?;
    let f: Vec<f64> = points.iter().map(|p| p.freq_hz).collect();
    let mf: Vec<f64> = model.iter().map(|m| m.0).collect();
    let model_series = |y: Vec<f64>| Series::line("model (sampled loop)", mf.clone(), y);
    let series = |get: fn(&studies::frf::FrfPoint) -> f64, label: &str, pts: bool| Series {
        label: label.into(),
        x: f.clone(),
        y: points.iter().map(get).collect(),
        points: pts,
    };
    let mag = Figure {
        title: String::new(),
        x_label: "frequency (Hz)".into(),
        y_label: "|H| (µm/V)".into(),
        log_x: true,
        log_y: true,
        series: vec![
            model_series(model.iter().map(|m| m.1.norm() * 1e6).collect()),
            series(|p| p.magnitude * 1e6, "measured (stepped sine)", true),
        ],
    };
    // Unwrap the model along its dense grid; place each measured phase on the same branch.
    let mut unwrapped: Vec<f64> = Vec::with_capacity(model.len());
    for m in model {
        let mut p = m.1.arg().to_degrees();
        if let Some(&prev) = unwrapped.last() {
            p += 360.0 * ((prev - p) / 360.0).round();
        }
        unwrapped.push(p);
    }
    let branch = |f: f64, p: f64| {
        let i = mf
            .iter()
            .position(|&x| x >= f)
            .unwrap_or(mf.len().saturating_sub(1));
        let reference = unwrapped.get(i).copied().unwrap_or(p);
        p + 360.0 * ((reference - p) / 360.0).round()
    };
    let measured_phase = Series {
        label: "measured (stepped sine)".into(),
        x: f.clone(),
        y: points
            .iter()
            .map(|p| branch(p.freq_hz, p.phase_deg))
            .collect(),
        points: true,
    };
    let phase = Figure {
        title: String::new(),
        x_label: "frequency (Hz)".into(),
        y_label: "phase (°)".into(),
        log_x: true,
        log_y: false,
        series: vec![model_series(unwrapped.clone()), measured_phase],
    };
    let bode = plot::Stacked {
        title: format!("{title}: Bode plot"),
        top: mag,
        bottom: phase,
    };
    out.note = plot_file(&bode, &dir.join("bode"), &mut out.files);
    Ok(out)
}
