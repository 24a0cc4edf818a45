//! Controller files: a discrete state-space controller designed elsewhere (`servo synth`,
//! MATLAB, python-control) as TOML, checked for shape, finiteness and sample rate.

use crate::config::MadeFor;
use crate::config::{ConfigError, Origin};
use nalgebra::DMatrix;
use serde::Deserialize;
use std::path::Path;

/// Largest state-space controller order `servo run` accepts (the thesis's full order is 27).
pub const MAX_SS_ORDER: usize = 40;

/// A controller file: the discrete controller `x⁺ = A x + B e`, `u = C x + D e` from the
/// position error `e = reference − measurement` in sensor volts to the command in volts.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SsFile {
    /// The sample rate the matrices were designed for, in Hz (must equal the servo rate).
    pub sample_rate_hz: f64,
    /// n × n.
    pub a: Vec<Vec<f64>>,
    /// n × 1.
    pub b: Vec<Vec<f64>>,
    /// 1 × n.
    pub c: Vec<Vec<f64>>,
    /// 1 × 1.
    pub d: Vec<Vec<f64>>,
    /// What it was designed for (`servo synth` writes it; files from elsewhere may omit it and
    /// are checked for their sample rate only).
    pub made_for: Option<MadeFor>,
}

/// A loaded controller file: `[[A, B], [C, D]]` and its order.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerFile {
    /// `[[A, B], [C, D]]`, (n + 1) × (n + 1).
    pub m: DMatrix<f64>,
    /// Order n.
    pub n: usize,
}

impl ControllerFile {
    /// Parses the text of the controller file `path` (errors located there), checking shapes,
    /// finiteness, that it was designed for the run's servo rate, and — when it says what it
    /// was made for — for the run's plant (`run`), unless `force`.
    pub fn parse(text: &str, path: &Path, run: &MadeFor, force: bool) -> Result<Self, ConfigError> {
        let servo_rate_hz = run.servo_rate_hz;
        let file: SsFile = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })?;
        let at = Origin {
            path: Some(path.to_owned()),
            text: Some(text.to_owned()),
        };
        let n = file.a.len();
        let shape = |key: &str, rows: &Vec<Vec<f64>>, r: usize, c: usize| {
            let ok = rows.len() == r
                && rows
                    .iter()
                    .all(|row| row.len() == c && row.iter().all(|x| x.is_finite()));
            if ok {
                Ok(())
            } else {
                let got = format!("{}×{}", rows.len(), rows.first().map_or(0, |x| x.len()));
                Err(at.invalid(
                    key,
                    got,
                    &format!(
                        "{r}×{c} finite numbers (controller order {n}, one input, one output)"
                    ),
                ))
            }
        };
        if n == 0 || n > MAX_SS_ORDER {
            return Err(at.invalid(
                "a",
                format!("{n} states"),
                &format!("1..={MAX_SS_ORDER} states"),
            ));
        }
        shape("a", &file.a, n, n)?;
        shape("b", &file.b, n, 1)?;
        shape("c", &file.c, 1, n)?;
        shape("d", &file.d, 1, 1)?;
        let off = (file.sample_rate_hz - servo_rate_hz).abs();
        if off.is_nan() || off > 1e-6 * servo_rate_hz {
            return Err(at.invalid(
                "sample_rate_hz",
                file.sample_rate_hz,
                &format!("{servo_rate_hz} Hz (the run's plant.timing.servo_rate_hz)"),
            ));
        }
        if let Some(made_for) = &file.made_for {
            made_for.check(run, &at, "made_for", force)?;
        }
        let mut m = DMatrix::zeros(n + 1, n + 1);
        for i in 0..n {
            for j in 0..n {
                m[(i, j)] = file.a[i][j];
            }
            m[(i, n)] = file.b[i][0];
            m[(n, i)] = file.c[0][i];
        }
        m[(n, n)] = file.d[0][0];
        Ok(ControllerFile { m, n })
    }
}
