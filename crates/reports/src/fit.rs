//! `fit.csv`, `fit.json` and the plot of `servo fit`: the measured FRF, the rational fit and
//! the plant model over it, and each bin's residual in units of its uncertainty.

use crate::plot::{self, Figure, Series};
use crate::plot_file;
use num_complex::Complex64;
use run_config::frf_file::MeasuredFrf;
use std::fmt::Write as _;
use std::path::Path;
use studies::fit::{FrfFit, DISK_95};
use studies::report::{data, ReportError, Written};

/// What `fit.json` holds: the FRF's source and the fit (its rational model included).
#[derive(serde::Serialize)]
struct FitFile<'a> {
    source: &'a str,
    #[serde(flatten)]
    fit: &'a FrfFit,
}

/// Writes `fit.csv` (per bin: measured, fit, uncertainty, residual in σ), `fit.json` and
/// `fit.{png,svg}` into `dir`; `model` is the plant model's response on a dense grid `(Hz,
/// m/V)`.
pub fn write(
    frf: &MeasuredFrf,
    fit: &FrfFit,
    model: &[(f64, Complex64)],
    dir: &Path,
) -> Result<Written, ReportError> {
    let sigma = frf.uncertainty.as_deref().unwrap_or(&[]);
    let mut csv = format!(
        "# fts-servo fit of {}: order {}, unit m/V\n\
         freq_hz,magnitude_m_per_v,phase_deg,uncertainty_m_per_v,fit_magnitude_m_per_v,fit_phase_deg,residual_sigmas\n",
        frf.source,
        fit.order
    );
    let mut residual = Vec::with_capacity(frf.freq_hz.len());
    for (k, &f) in frf.freq_hz.iter().enumerate() {
        let (h, g) = (frf.response[k], fit.fit.response(f));
        let s = sigma.get(k).copied().unwrap_or(f64::NAN);
        residual.push((g - h).norm() / s);
        writeln!(
            csv,
            "{f:.6},{:.6e},{:.4},{s:.3e},{:.6e},{:.4},{:.4}",
            h.norm(),
            h.arg().to_degrees(),
            g.norm(),
            g.arg().to_degrees(),
            residual[k]
        )
        .unwrap();
    }
    let file = FitFile {
        source: &frf.source,
        fit,
    };
    let mut out = data(
        dir,
        "fit",
        "a rational fit of a measured FRF (servo fit)",
        &csv,
        &file,
    )?;
    let dense: Vec<f64> = model.iter().map(|m| m.0).collect();
    let um = |c: Complex64| c.norm() * 1e6;
    let magnitude = Figure {
        title: String::new(),
        x_label: "frequency (Hz)".into(),
        y_label: "|P| (µm/V)".into(),
        log_x: true,
        log_y: true,
        series: vec![
            Series::line(
                "plant model",
                dense.clone(),
                model.iter().map(|m| um(m.1)).collect(),
            ),
            Series::line(
                format!("rational fit, order {}", fit.order),
                dense.clone(),
                dense.iter().map(|&f| um(fit.fit.response(f))).collect(),
            ),
            Series {
                label: "measured".into(),
                x: frf.freq_hz.clone(),
                y: frf.response.iter().map(|&h| um(h)).collect(),
                points: true,
            },
        ],
    };
    let ends = vec![frf.freq_hz[0], frf.freq_hz[frf.freq_hz.len() - 1]];
    let residuals = Figure {
        title: String::new(),
        x_label: "frequency (Hz)".into(),
        y_label: "|fit − measured| / σ".into(),
        log_x: true,
        log_y: false,
        series: vec![
            Series::line("95 % disk", ends, vec![DISK_95; 2]),
            Series {
                label: "residual per bin".into(),
                x: frf.freq_hz.clone(),
                y: residual,
                points: true,
            },
        ],
    };
    let drawing = plot::Stacked {
        title: format!(
            "Rational fit of the measured FRF: order {}, {:.1} % of bins within their 95 % disk",
            fit.order,
            100.0 * fit.within
        ),
        top: magnitude,
        bottom: residuals,
    };
    out.note = plot_file(&drawing, &dir.join("fit"), &mut out.files);
    Ok(out)
}
