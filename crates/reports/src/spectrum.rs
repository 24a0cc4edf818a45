//! `spectrum.csv`, `spectrum.json` and the PSD, CAS and control-output plots of a recording
//! beside its budget (Fig 5-15).

use crate::plot::{Figure, Series};
use crate::plot_files;
use lti::spectral::cas_of_bins;
use std::fmt::Write as _;
use std::path::Path;
use studies::report::{data, ReportError, Written};
use studies::spectrum::{Signals, Spectrum};

/// Writes the data and the plots into `dir`; `title` names the recording.
pub fn write(s: &Spectrum, title: &str, dir: &Path) -> Result<Written, ReportError> {
    let mut out = data(
        dir,
        "spectrum",
        "spectra of a recording beside its budget, thesis §5.7.4 (servo spectrum)",
        &csv(s),
        s,
    )?;
    let f = &s.freq_hz;
    let scaled = |v: &[f64], k: f64| v.iter().map(|x| x * k).collect::<Vec<f64>>();
    let mut psd = Vec::new();
    let mut cas = Vec::new();
    let mut add = |name: &str, rec: &[f64], pred: Option<&[f64]>| {
        psd.push(Series::line(
            format!("{name}, recorded"),
            f.clone(),
            scaled(rec, 1e18),
        ));
        cas.push(Series::line(
            format!("{name}, recorded"),
            f.clone(),
            scaled(&cas_of_bins(rec, s.resolution_hz), 1e9),
        ));
        if let Some(p) = pred {
            psd.push(Series::line(
                format!("{name}, budget"),
                f.clone(),
                scaled(p, 1e18),
            ));
            cas.push(Series::line(
                format!("{name}, budget"),
                f.clone(),
                scaled(&cas_of_bins(p, s.resolution_hz), 1e9),
            ));
        }
    };
    let p = s.predicted_psd.as_ref();
    add(
        "following error",
        &s.recorded_psd.following_error_m,
        p.map(|p| p.following_error_m.as_slice()),
    );
    if let Some(t) = &s.recorded_psd.true_error_m {
        add("true error", t, p.and_then(|p| p.true_error_m.as_deref()));
    }
    let mut control = vec![Series::line(
        "control output, recorded",
        f.clone(),
        scaled(&s.recorded_psd.control_v, 1e6),
    )];
    if let Some(p) = p {
        control.push(Series::line(
            "control output, budget",
            f.clone(),
            scaled(&p.control_v, 1e6),
        ));
    }
    let figure = |what: &str, y_label: &str, log_y: bool, series: Vec<Series>| Figure {
        title: format!("{what} — {title}"),
        x_label: "frequency (Hz)".into(),
        y_label: y_label.into(),
        log_x: true,
        log_y,
        series,
    };
    out.note = plot_files(
        &[
            (
                figure(
                    "Error PSD, recording vs budget (thesis Fig 5-15)",
                    "PSD (nm²/Hz)",
                    true,
                    psd,
                ),
                "spectrum_psd",
            ),
            (
                figure(
                    "Cumulative amplitude spectrum (eq 5-16)",
                    "CAS (nm RMS)",
                    false,
                    cas,
                ),
                "spectrum_cas",
            ),
            (
                figure("Control output PSD", "PSD (mV²/Hz)", true, control),
                "spectrum_control",
            ),
        ],
        dir,
        &mut out.files,
    );
    Ok(out)
}

/// One row per bin: recorded and predicted PSD of each signal (empty where absent).
fn csv(s: &Spectrum) -> String {
    let mut out = format!(
        "# fts-servo spectrum: made for {}; {}; controller {}\n",
        s.made_for.describe(),
        s.made_for.tool,
        s.controller
    );
    out += "freq_hz,following_recorded_m2_per_hz,following_budget_m2_per_hz,\
            true_recorded_m2_per_hz,true_budget_m2_per_hz,control_recorded_v2_per_hz,control_budget_v2_per_hz\n";
    let at = |v: Option<&Vec<f64>>, i: usize| v.map_or(String::new(), |v| format!("{:.6e}", v[i]));
    let r: &Signals<Vec<f64>> = &s.recorded_psd;
    let p = s.predicted_psd.as_ref();
    for (i, f) in s.freq_hz.iter().enumerate() {
        writeln!(
            out,
            "{f:.6e},{},{},{},{},{},{}",
            at(Some(&r.following_error_m), i),
            at(p.map(|p| &p.following_error_m), i),
            at(r.true_error_m.as_ref(), i),
            at(p.and_then(|p| p.true_error_m.as_ref()), i),
            at(Some(&r.control_v), i),
            at(p.map(|p| &p.control_v), i),
        )
        .unwrap();
    }
    out
}
