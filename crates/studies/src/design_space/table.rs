//! The study's table as CSV: one row per point with the parameter values, the status and the
//! reason of a failed point, and the metrics. Numbers are written in the shortest form that
//! reads back to the same `f64` (so a table written, read and written again is the same bytes,
//! and a merged table equals a single run's); a missing number (failed point, no margin) is an
//! empty field.

use super::evaluate::{Metrics, Point, SOURCE_COUNT};
use super::spec::Study;
use loop_model::closed_loop::SOURCES;
use std::fmt::Write as _;

/// The metrics of a point before the per-source columns, with their units in the names.
const SCALAR_COLUMNS: [&str; 11] = [
    "bandwidth_hz",
    "following_rms_m",
    "true_rms_m",
    "spectral_radius",
    "phase_margin_deg",
    "gain_margin_db",
    "controller_states",
    "design_value",
    "kp_v_per_v",
    "ki_v_per_v_s",
    "kd_v_s_per_v",
];

/// Number of metric columns: the scalars, then following and true RMS per source.
pub const METRIC_COUNT: usize = SCALAR_COLUMNS.len() + 2 * SOURCE_COUNT;

/// The metric columns after the parameters, status and reason, with their units in the names.
pub fn metric_columns() -> Vec<String> {
    let mut c: Vec<String> = SCALAR_COLUMNS.map(String::from).to_vec();
    for out in ["following", "true"] {
        for (name, _) in SOURCES {
            c.push(format!("{out}_{}_m", name.replace(' ', "_")));
        }
    }
    c
}

/// The header line (without newline): `index,controller,<parameter keys>,status,reason,<metrics>`.
pub fn header(study: &Study) -> String {
    let mut h = vec!["index".to_owned(), "controller".to_owned()];
    h.extend(study.table.parameters.iter().map(|p| p.key.clone()));
    h.extend(["status".to_owned(), "reason".to_owned()]);
    h.extend(metric_columns());
    h.join(",")
}

/// A number's field: shortest round-trip form, empty for NaN.
fn number(v: f64) -> String {
    if v.is_nan() {
        String::new()
    } else {
        format!("{v:e}")
    }
}

impl Metrics {
    /// The metric values in [`metric_columns`] order.
    pub fn columns(&self) -> Vec<f64> {
        let mut v = vec![
            self.bandwidth_hz,
            self.following_rms_m,
            self.true_rms_m,
            self.spectral_radius,
            self.phase_margin_deg,
            self.gain_margin_db,
            self.controller_states as f64,
            self.design_value,
            self.pid[0],
            self.pid[1],
            self.pid[2],
        ];
        v.extend(&self.following_by_source_m);
        v.extend(&self.true_by_source_m);
        v
    }

    fn from_columns(v: &[f64]) -> Option<Metrics> {
        let s = SCALAR_COLUMNS.len();
        if v.len() != METRIC_COUNT {
            return None;
        }
        Some(Metrics {
            bandwidth_hz: v[0],
            following_rms_m: v[1],
            true_rms_m: v[2],
            spectral_radius: v[3],
            phase_margin_deg: v[4],
            gain_margin_db: v[5],
            controller_states: v[6] as usize,
            design_value: v[7],
            pid: [v[8], v[9], v[10]],
            following_by_source_m: v[s..s + SOURCE_COUNT].to_vec(),
            true_by_source_m: v[s + SOURCE_COUNT..].to_vec(),
        })
    }
}

/// A point as one CSV line (with its newline).
pub fn row(p: &Point) -> String {
    let mut line = format!("{},{}", p.index, p.family.name());
    for v in &p.values {
        write!(line, ",{}", number(*v)).expect("writing to a String");
    }
    match &p.outcome {
        Ok(m) => {
            line.push_str(",ok,");
            for v in m.columns() {
                write!(line, ",{}", number(v)).expect("writing to a String");
            }
        }
        Err(reason) => {
            let quoted = reason.replace(['\n', '\r'], " ").replace('"', "\"\"");
            write!(line, ",failed,\"{quoted}\"").expect("writing to a String");
            line.push_str(&",".repeat(METRIC_COUNT));
        }
    }
    line.push('\n');
    line
}

/// Splits a CSV line into fields (double-quoted fields may hold commas and `""`).
fn fields(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                chars.next();
                out.last_mut().expect("one field at least").push('"');
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(String::new()),
            _ => out.last_mut().expect("one field at least").push(c),
        }
    }
    out
}

/// Reads a row written by [`row`] for `study` (None: not a complete row of this study).
pub fn parse_row(study: &Study, line: &str) -> Option<Point> {
    let f = fields(line);
    let np = study.table.parameters.len();
    if f.len() != 4 + np + METRIC_COUNT {
        return None;
    }
    let num = |s: &str| -> Option<f64> {
        if s.is_empty() {
            Some(f64::NAN)
        } else {
            s.parse().ok()
        }
    };
    let family = study
        .table
        .controllers
        .iter()
        .copied()
        .find(|c| c.name() == f[1])?;
    let values = f[2..2 + np]
        .iter()
        .map(|s| num(s))
        .collect::<Option<Vec<_>>>()?;
    let outcome = match f[2 + np].as_str() {
        "ok" => {
            let m = f[4 + np..]
                .iter()
                .map(|s| num(s))
                .collect::<Option<Vec<_>>>()?;
            Ok(Metrics::from_columns(&m)?)
        }
        "failed" => Err(f[3 + np].clone()),
        _ => return None,
    };
    Some(Point {
        index: f[0].parse().ok()?,
        family,
        values,
        outcome,
    })
}

/// The whole table: the header and the points in index order.
pub fn csv(study: &Study, points: &[Point]) -> String {
    let mut out = header(study);
    out.push('\n');
    for p in points {
        out.push_str(&row(p));
    }
    out
}
