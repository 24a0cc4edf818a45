//! Analysis results as data first (CSV with a header naming column and unit, JSON), pictures
//! second (PNG + SVG), all in one output directory.

use crate::analysis::{Budget, SOURCES};
use crate::sweep::Sweep;
use design::plot::{self, Figure, Series};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Report errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Writing a file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

fn write_file(path: PathBuf, text: &str) -> Result<PathBuf, ReportError> {
    std::fs::write(&path, text).map_err(|source| ReportError::Io {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// Creates `dir` and writes `files` (file name, contents) into it.
fn write_files(dir: &Path, files: &[(&str, &str)]) -> Result<Written, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.to_owned(),
        source,
    })?;
    Ok(Written {
        files: files
            .iter()
            .map(|(name, text)| write_file(dir.join(name), text))
            .collect::<Result<_, _>>()?,
        note: None,
    })
}

/// Pretty JSON of an analysis result.
fn to_json<T: serde::Serialize + ?Sized>(value: &T) -> String {
    serde_json::to_string_pretty(value).expect("analysis results serialise")
}

/// Creates `dir` and writes the data files `<stem>.csv` and `<stem>.json`.
fn data<T: serde::Serialize + ?Sized>(
    dir: &Path,
    stem: &str,
    csv: &str,
    json: &T,
) -> Result<Written, ReportError> {
    write_files(
        dir,
        &[
            (&format!("{stem}.csv"), csv),
            (&format!("{stem}.json"), &to_json(json)),
        ],
    )
}

/// Writes the plots, or returns the reason they were skipped (no font) as a note.
fn plots(figs: &[(Figure, &str)], dir: &Path, written: &mut Vec<PathBuf>) -> Option<String> {
    for (fig, stem) in figs {
        match plot::write(fig, &dir.join(stem)) {
            Ok(paths) => written.extend(paths),
            Err(e) => return Some(e.to_string()),
        }
    }
    None
}

/// Files written, and a note if plots were skipped.
#[derive(Debug, Default)]
pub struct Written {
    /// Paths written.
    pub files: Vec<PathBuf>,
    /// Why plots were skipped, if they were.
    pub note: Option<String>,
}

/// `budget.csv`, `budget.json`, `budget_psd.{png,svg}`, `budget_cas.{png,svg}`.
pub fn budget(b: &Budget, title: &str, dir: &Path) -> Result<Written, ReportError> {
    let mut csv = String::from("freq_hz");
    for (name, _) in SOURCES {
        let n = name.replace(' ', "_");
        write!(csv, ",following_psd_{n}_m2_per_hz,true_psd_{n}_m2_per_hz").unwrap();
    }
    csv.push_str(",following_cas_m,true_cas_m\n");
    for (i, f) in b.freq_hz.iter().enumerate() {
        write!(csv, "{f:.6e}").unwrap();
        for k in 0..SOURCES.len() {
            write!(
                csv,
                ",{:.6e},{:.6e}",
                b.following_psd[k][i], b.true_psd[k][i]
            )
            .unwrap();
        }
        writeln!(csv, ",{:.6e},{:.6e}", b.following_cas[i], b.true_cas[i]).unwrap();
    }
    let mut out = data(dir, "budget", &csv, b)?;
    let nm2 = |v: &Vec<f64>| v.iter().map(|x| x * 1e18).collect::<Vec<f64>>();
    let total = |psd: &Vec<Vec<f64>>| {
        (0..b.freq_hz.len())
            .map(|i| psd.iter().map(|p| p[i]).sum::<f64>())
            .collect::<Vec<f64>>()
    };
    let mut psd_series = vec![
        Series::line(
            "following error, total",
            b.freq_hz.clone(),
            nm2(&total(&b.following_psd)),
        ),
        Series::line(
            "true error, total",
            b.freq_hz.clone(),
            nm2(&total(&b.true_psd)),
        ),
    ];
    for (k, (name, _)) in SOURCES.iter().enumerate() {
        if b.contributions[k].following_rms_m > 1e-3 * b.following_rms_m {
            psd_series.push(Series::line(
                format!("following, {name}"),
                b.freq_hz.clone(),
                nm2(&b.following_psd[k]),
            ));
        }
    }
    let psd = Figure {
        title: format!("Error PSD budget (thesis Fig 5-15) — {title}"),
        x_label: "frequency (Hz)".into(),
        y_label: "PSD (nm²/Hz)".into(),
        log_x: true,
        log_y: true,
        series: psd_series,
    };
    let nm = |v: &Vec<f64>| v.iter().map(|x| x * 1e9).collect::<Vec<f64>>();
    let cas = Figure {
        title: format!("Cumulative amplitude spectrum (eq 5-16) — {title}"),
        x_label: "frequency (Hz)".into(),
        y_label: "CAS (nm RMS)".into(),
        log_x: true,
        log_y: false,
        series: vec![
            Series::line("following error", b.freq_hz.clone(), nm(&b.following_cas)),
            Series::line("true error", b.freq_hz.clone(), nm(&b.true_cas)),
        ],
    };
    out.note = plots(
        &[(psd, "budget_psd"), (cas, "budget_cas")],
        dir,
        &mut out.files,
    );
    Ok(out)
}

/// `sweep.csv`, `sweep.json`, `sweep.{png,svg}` (thesis Fig 5-14).
pub fn sweeps(sweeps: &[Sweep], dir: &Path) -> Result<Written, ReportError> {
    let mut csv = String::from("label,target_hz,bandwidth_hz,gain_scale,predicted_following_m,predicted_true_m,simulated_following_m,simulated_true_m\n");
    for s in sweeps {
        for p in &s.points {
            let opt = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.6e}"));
            writeln!(
                csv,
                "{},{:.1},{:.3},{:.6},{:.6e},{:.6e},{},{}",
                s.label,
                p.target_hz,
                p.bandwidth_hz,
                p.gain_scale,
                p.predicted_following_m,
                p.predicted_true_m,
                opt(p.simulated_following_m),
                opt(p.simulated_true_m)
            )
            .unwrap();
        }
    }
    let mut out = data(dir, "sweep", &csv, sweeps)?;
    let mut series = Vec::new();
    for s in sweeps {
        let bw: Vec<f64> = s.points.iter().map(|p| p.bandwidth_hz).collect();
        let nm = |f: fn(&crate::sweep::SweepPoint) -> Option<f64>| {
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
        log_x: true,
        log_y: false,
        series,
    };
    out.note = plots(&[(fig, "sweep")], dir, &mut out.files);
    Ok(out)
}

/// `frf.csv`, `frf.json`, `bode_magnitude.{png,svg}`, `bode_phase.{png,svg}`.
pub fn frf(
    points: &[crate::frf::FrfPoint],
    model: &[(f64, num_complex::Complex64)],
    title: &str,
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut csv = String::from("freq_hz,magnitude_m_per_v,phase_deg,coherence,model_magnitude_m_per_v,model_phase_deg,clipped\n");
    for p in points {
        writeln!(
            csv,
            "{:.6},{:.6e},{:.4},{:.6},{:.6e},{:.4},{}",
            p.freq_hz,
            p.magnitude,
            p.phase_deg,
            p.coherence,
            p.model_magnitude,
            p.model_phase_deg,
            p.clipped
        )
        .unwrap();
    }
    let mut out = data(dir, "frf", &csv, points)?;
    let f: Vec<f64> = points.iter().map(|p| p.freq_hz).collect();
    let mf: Vec<f64> = model.iter().map(|m| m.0).collect();
    let model_series = |y: Vec<f64>| Series::line("model (sampled loop)", mf.clone(), y);
    let series = |get: fn(&crate::frf::FrfPoint) -> f64, label: &str, pts: bool| Series {
        label: label.into(),
        x: f.clone(),
        y: points.iter().map(get).collect(),
        points: pts,
    };
    let mag = Figure {
        title: format!("{title}: magnitude"),
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
        title: format!("{title}: phase"),
        x_label: "frequency (Hz)".into(),
        y_label: "phase (°)".into(),
        log_x: true,
        log_y: false,
        series: vec![model_series(unwrapped.clone()), measured_phase],
    };
    out.note = plots(
        &[(mag, "bode_magnitude"), (phase, "bode_phase")],
        dir,
        &mut out.files,
    );
    Ok(out)
}

/// `stiffness.csv`, `stiffness.json`, `compliance.{png,svg}` (thesis Fig 7-7, 7-14).
pub fn stiffness(
    curves: &[crate::stiffness::ComplianceCurve],
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
    let mut out = data(dir, "stiffness", &csv, curves)?;
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
    out.note = plots(&[(fig, "compliance")], dir, &mut out.files);
    Ok(out)
}

/// Picture columns of the form-error map (the data keep every 0.1° bin).
const MAP_PICTURE_COLUMNS: usize = 720;

/// `machine.json` (the [`FormReport`](crate::form::FormReport)), `form_map.csv`,
/// `trajectory.csv`, and the pictures `form_error_map`, `trajectory`, `trajectory_error`
/// (PNG + SVG).
pub fn machining(
    a: &crate::form::FormAnalysis,
    title: &str,
    dir: &Path,
) -> Result<Written, ReportError> {
    use crate::form::MAP_COLUMNS;
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
            ("machine.json", &to_json(&report)),
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
    let map = plot::Map {
        title: format!("Form error, tool − design (nm) — {title}"),
        x_label: "spindle angle (°)".into(),
        y_label: "radius (mm)".into(),
        x: (0.0, 360.0),
        y: ((outer - ring * rows as f64) * 1e3, outer * 1e3),
        cols: MAP_PICTURE_COLUMNS,
        values: picture,
    };
    let ms: Vec<f64> = a.segment().iter().map(|s| s.time_s * 1e3).collect();
    let um = |f: fn(&crate::form::SegmentRow) -> f64| -> Vec<f64> {
        a.segment().iter().map(|s| f(s) * 1e6).collect()
    };
    let nm = |f: fn(&crate::form::SegmentRow) -> f64| -> Vec<f64> {
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
                "following error (command − measured)",
                nm(|s| s.reference_m - s.measured_m),
            ),
        ],
    };
    out.note = plots(
        &[(trajectory, "trajectory"), (errors, "trajectory_error")],
        dir,
        &mut out.files,
    );
    if out.note.is_none() {
        match plot::write_map(&map, &dir.join("form_error_map")) {
            Ok(paths) => out.files.extend(paths),
            Err(e) => out.note = Some(e.to_string()),
        }
    }
    Ok(out)
}

/// `spindle.json`, `spindle.csv` (one revolution: truth and every estimate),
/// `harmonic_weighting.csv`, and the pictures `harmonic_weighting` (Fig D-2), `artefact`
/// (Fig D-7) and `x_motion` (Fig D-8).
pub fn spindle(
    r: &crate::spindle::SpindleReport,
    p: &crate::spindle::SpindleProfiles,
    max_harmonic: usize,
    dir: &Path,
) -> Result<Written, ReportError> {
    let sets = p.sets.len();
    let mut csv = String::from("angle_deg,artefact_true_m,x_true_m,y_true_m");
    for i in 1..=sets {
        write!(
            csv,
            ",artefact_set{i}_m,artefact_set{i}_modified_m,x_set{i}_m"
        )
        .unwrap();
    }
    csv.push_str(",artefact_synthesised_m,x_synthesised_m,y_synthesised_m\n");
    for (j, a) in p.angle_deg.iter().enumerate() {
        write!(
            csv,
            "{a:.4},{:.6e},{:.6e},{:.6e}",
            p.truth[0][j], p.truth[1][j], p.truth[2][j]
        )
        .unwrap();
        for (s, m) in p.sets.iter().zip(&p.modified) {
            write!(
                csv,
                ",{:.6e},{:.6e},{:.6e}",
                s.artefact[j], m.artefact[j], s.x[j]
            )
            .unwrap();
        }
        let y = &p.synthesised;
        writeln!(csv, ",{:.6e},{:.6e},{:.6e}", y.artefact[j], y.x[j], y.y[j]).unwrap();
    }
    let ks: Vec<f64> = (2..=max_harmonic).map(|k| k as f64).collect();
    let h: Vec<Vec<f64>> = p
        .sets
        .iter()
        .map(|s| {
            (2..=max_harmonic)
                .map(|k| design::spindle::harmonic_weighting(&s.angles, k).norm())
                .collect()
        })
        .collect();
    let mut hcsv = String::from("harmonic_upr");
    for i in 1..=sets {
        write!(hcsv, ",abs_h_set{i}").unwrap();
    }
    hcsv.push('\n');
    for (i, k) in ks.iter().enumerate() {
        write!(hcsv, "{k}").unwrap();
        for hs in &h {
            write!(hcsv, ",{:.6}", hs[i]).unwrap();
        }
        hcsv.push('\n');
    }
    let mut out = write_files(
        dir,
        &[
            ("spindle.csv", &csv),
            ("spindle.json", &to_json(r)),
            ("harmonic_weighting.csv", &hcsv),
        ],
    )?;
    let nm = |v: &[f64]| v.iter().map(|x| x * 1e9).collect::<Vec<f64>>();
    let weighting = Figure {
        title: "Harmonic weighting |H(k)| of the three angle sets (thesis Fig D-2)".into(),
        x_label: "harmonic (UPR)".into(),
        y_label: "|H(k)|".into(),
        log_x: false,
        log_y: false,
        series: h
            .into_iter()
            .enumerate()
            .map(|(i, y)| Series::line(format!("angle set #{}", i + 1), ks.clone(), y))
            .collect(),
    };
    let mut artefact = vec![Series::line(
        "true artefact",
        p.angle_deg.clone(),
        nm(&p.truth[0]),
    )];
    artefact.extend(p.sets.iter().enumerate().map(|(i, s)| {
        Series::line(
            format!("set #{} alone", i + 1),
            p.angle_deg.clone(),
            nm(&s.artefact),
        )
    }));
    artefact.push(Series::line(
        "synthesised",
        p.angle_deg.clone(),
        nm(&p.synthesised.artefact),
    ));
    let artefact = Figure {
        title: "Separated artefact form (thesis Fig D-7)".into(),
        x_label: "spindle angle (°)".into(),
        y_label: "form (nm)".into(),
        log_x: false,
        log_y: false,
        series: artefact,
    };
    let x_motion = Figure {
        title: "Synchronous X radial error motion (thesis Fig D-8)".into(),
        x_label: "spindle angle (°)".into(),
        y_label: "X (nm)".into(),
        log_x: false,
        log_y: false,
        series: vec![
            Series::line("true", p.angle_deg.clone(), nm(&p.truth[1])),
            Series::line("synthesised", p.angle_deg.clone(), nm(&p.synthesised.x)),
        ],
    };
    out.note = plots(
        &[
            (weighting, "harmonic_weighting"),
            (artefact, "artefact"),
            (x_motion, "x_motion"),
        ],
        dir,
        &mut out.files,
    );
    Ok(out)
}

/// `intermittent.csv` and `intermittent.json`: the Ka table of the intermittent cut.
pub fn intermittent(
    rows: &[crate::intermittent::KaRow],
    dir: &Path,
) -> Result<Written, ReportError> {
    let mut csv = String::from(
        "ka_v_per_v,pid_scale,peak_following_error_m,edge_form_error_m,following_rms_m\n",
    );
    for r in rows {
        writeln!(
            csv,
            "{},{:.6},{:.6e},{:.6e},{:.6e}",
            r.ka, r.pid_scale, r.peak_following_error_m, r.edge_form_error_m, r.following_rms_m
        )
        .unwrap();
    }
    data(dir, "intermittent", &csv, rows)
}
