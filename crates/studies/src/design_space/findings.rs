//! What a finished study found and the data it writes: the table (`study.csv`,
//! `study.parquet`), `study.json` (the description, counts, failure reasons, optima,
//! sensitivities) and `sensitivity.csv` (its plots are the `reports` crate's).

use super::evaluate::Point;
use super::sensitivity::Sensitivity;
use super::spec::{Objective, Study};
use super::{columnar, optima, table, Optimum};
use crate::report::{to_json, write_files, ReportError, Written};
use loop_model::closed_loop::SOURCES;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// Points that failed for one reason.
#[derive(Debug, Serialize)]
pub struct Failures {
    /// The reason.
    pub reason: String,
    /// How many points.
    pub points: u64,
    /// The first point's index.
    pub first_index: u64,
}

/// What a finished study found: counts, failures, optima, sensitivities (computed once, for
/// `study.json` and for the caller to print).
#[derive(Debug, Serialize)]
pub struct Findings {
    /// Points in all.
    pub points: u64,
    /// Points whose loop was built and evaluated.
    pub ok: u64,
    /// Failed points, by reason (most frequent first).
    pub failures: Vec<Failures>,
    /// The error the optima are about.
    pub objective: Objective,
    /// The best point of each family.
    pub optima: Vec<Optimum>,
    /// Elasticities at the operating point.
    pub sensitivities: Vec<Sensitivity>,
}

impl Findings {
    /// The findings of `points` (index order) of `study`, with its `sensitivities`.
    pub fn new(study: &Study, points: &[Point], sensitivities: Vec<Sensitivity>) -> Self {
        Findings {
            points: points.len() as u64,
            ok: points.iter().filter(|p| p.outcome.is_ok()).count() as u64,
            failures: failures(points),
            objective: study.table.objective,
            optima: optima(study, points),
            sensitivities,
        }
    }
}

/// `study.json` (after its metadata).
#[derive(Debug, Serialize)]
struct Summary<'a> {
    name: &'a str,
    study_sha256: &'a str,
    description: &'a str,
    #[serde(flatten)]
    findings: &'a Findings,
}

/// The failed points grouped by reason.
pub fn failures(points: &[Point]) -> Vec<Failures> {
    let mut out: Vec<Failures> = Vec::new();
    for p in points {
        if let Err(reason) = &p.outcome {
            match out.iter_mut().find(|f| &f.reason == reason) {
                Some(f) => f.points += 1,
                None => out.push(Failures {
                    reason: reason.clone(),
                    points: 1,
                    first_index: p.index,
                }),
            }
        }
    }
    out.sort_by_key(|f| std::cmp::Reverse(f.points));
    out
}

/// Writes a finished study's data into `dir`: the table (`study.csv`, `study.parquet`),
/// `study.json` (the description, counts, failure reasons, optima, sensitivities) and
/// `sensitivity.csv`.
pub fn write_data(
    study: &Study,
    points: &[Point],
    findings: &Findings,
    dir: &Path,
) -> Result<Written, ReportError> {
    let t = &study.table;
    let sensitivities = &findings.sensitivities;
    let summary = Summary {
        name: &t.name,
        study_sha256: &study.sha256,
        description: &study.text,
        findings,
    };
    let what = format!(
        "design-space study \"{}\" (thesis §6.5; servo study)",
        t.name
    );
    let mut out = write_files(
        dir,
        &[
            ("study.csv", &table::csv(study, points)),
            ("study.json", &to_json(&what, "study", &summary)),
            ("sensitivity.csv", &sensitivity_csv(sensitivities)),
        ],
    )?;
    let parquet = dir.join("study.parquet");
    columnar::write(study, points, &parquet)?;
    out.files.push(parquet);
    Ok(out)
}

fn sensitivity_csv(s: &[Sensitivity]) -> String {
    let mut csv = String::from("controller,key,operating_value,following,true");
    for out in ["following", "true"] {
        for (name, _) in SOURCES {
            write!(csv, ",{out}_{}", name.replace(' ', "_")).expect("writing to a String");
        }
    }
    csv.push_str(",failed\n");
    let n = |v: f64| {
        if v.is_nan() {
            String::new()
        } else {
            format!("{v:.6}")
        }
    };
    for e in s {
        write!(
            csv,
            "{},{},{:e},{},{}",
            e.controller.name(),
            e.key,
            e.operating_value,
            n(e.following),
            n(e.true_error)
        )
        .expect("writing to a String");
        for v in e.following_by_source.iter().chain(&e.true_by_source) {
            write!(csv, ",{}", n(*v)).expect("writing to a String");
        }
        writeln!(
            csv,
            ",{}",
            e.failed.as_deref().unwrap_or("").replace(',', ";")
        )
        .expect("writing to a String");
    }
    csv
}

/// A parameter key with its unit spelled out for an axis (`plant.stage.k2_n_per_m` →
/// `k2 (N/m)`).
pub fn axis_label(key: &str) -> String {
    let name = key.rsplit('.').next().unwrap_or(key);
    const UNITS: [(&str, &str); 9] = [
        ("_v_per_rt_hz", "V/√Hz"),
        ("_a_per_rt_hz", "A/√Hz"),
        ("_m_per_rt_hz", "m/√Hz"),
        ("_n_s_per_m", "N·s/m"),
        ("_n_per_m", "N/m"),
        ("_n_per_a", "N/A"),
        ("_kg", "kg"),
        ("_hz", "Hz"),
        ("_s", "s"),
    ];
    for (suffix, unit) in UNITS {
        if let Some(stem) = name.strip_suffix(suffix) {
            return format!("{stem} ({unit})");
        }
    }
    name.to_owned()
}
