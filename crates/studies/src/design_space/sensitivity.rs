//! Sensitivities at the operating point (thesis §6.5: "the current system design is used as
//! the operating point … the resulting following RMS errors are used to compare the
//! sensitivities"): for each parameter and family, the elasticity `d ln e / d ln p` of the total
//! and per-source RMS errors — the % change of the error per % change of the parameter — by a
//! central difference of ±5 % around the operating value, every other parameter held there.

use super::evaluate::{outcome, Metrics};
use super::spec::{Family, Study};
use serde::Serialize;

/// Relative step of the central difference.
pub const STEP: f64 = 0.05;

/// The elasticities of one parameter under one family.
#[derive(Debug, Clone, Serialize)]
pub struct Sensitivity {
    /// Controller family.
    pub controller: Family,
    /// Parameter key.
    pub key: String,
    /// Its operating value (the study file's), in the key's unit.
    pub operating_value: f64,
    /// d ln(RMS following error) / d ln(parameter).
    pub following: f64,
    /// d ln(RMS true error) / d ln(parameter).
    pub true_error: f64,
    /// The same per source (following error), [`loop_model::closed_loop::SOURCES`] order; NaN for
    /// a source that contributes nothing.
    pub following_by_source: Vec<f64>,
    /// The same per source (true error).
    pub true_by_source: Vec<f64>,
    /// Why it could not be computed, if it could not.
    pub failed: Option<String>,
}

fn elasticity(up: f64, down: f64) -> f64 {
    (libm::log(up) - libm::log(down)) / (libm::log(1.0 + STEP) - libm::log(1.0 - STEP))
}

/// The loops [`sensitivities`] evaluates: two per parameter and family.
pub fn loops(study: &Study) -> u64 {
    2 * (study.table.parameters.len() * study.table.controllers.len()) as u64
}

/// The sensitivities of every parameter under every family of `study` (2 loops each), the
/// loops evaluated on `jobs` threads. `progress` gets (done, total) evaluations.
pub fn sensitivities(
    study: &Study,
    jobs: usize,
    progress: &mut dyn FnMut(u64, u64),
) -> Vec<Sensitivity> {
    let params = &study.table.parameters;
    let operating: Vec<f64> = params.iter().map(|p| study.operating_value(p)).collect();
    let total = loops(study);
    // Each (family, parameter) with a relative step, evaluated at both sides.
    let cases: Vec<(Family, usize)> = study
        .table
        .controllers
        .iter()
        .flat_map(|&family| (0..params.len()).map(move |j| (family, j)))
        .collect();
    let steppable = |j: usize| {
        let whole = matches!(
            study.base_value(&params[j].key),
            Some(toml::Value::Integer(_))
        );
        !whole && operating[j] != 0.0 && operating[j].is_finite()
    };
    let loops: Vec<(usize, f64)> = (0..cases.len())
        .filter(|&c| steppable(cases[c].1))
        .flat_map(|c| [(c, 1.0 + STEP), (c, 1.0 - STEP)])
        .collect();
    let mut results: Vec<[Option<Result<Metrics, String>>; 2]> =
        cases.iter().map(|_| [None, None]).collect();
    let mut done = 2 * (cases.len() - loops.len() / 2) as u64;
    progress(done, total);
    let never = || false;
    super::execute::in_parallel(
        &loops,
        jobs,
        &never,
        |&(c, factor)| {
            let (family, j) = cases[c];
            let mut v = operating.clone();
            v[j] *= factor;
            (c, factor > 1.0, outcome(study, family, &v))
        },
        |(c, up, r)| {
            results[c][usize::from(!up)] = Some(r);
            done += 1;
            progress(done, total);
            true
        },
    );
    cases
        .iter()
        .zip(results)
        .map(|(&(family, j), [up, down])| {
            let result = match (up, down) {
                (Some(up), Some(down)) => up.and_then(|u| Ok((u, down?))),
                _ => Err(format!(
                    "no relative step from {} (a zero or whole-number operating value)",
                    operating[j]
                )),
            };
            let key = params[j].key.clone();
            let nan = vec![f64::NAN; super::evaluate::SOURCE_COUNT];
            match result {
                Ok((up, down)) => Sensitivity {
                    controller: family,
                    key,
                    operating_value: operating[j],
                    following: elasticity(up.following_rms_m, down.following_rms_m),
                    true_error: elasticity(up.true_rms_m, down.true_rms_m),
                    following_by_source: zip(
                        &up.following_by_source_m,
                        &down.following_by_source_m,
                    ),
                    true_by_source: zip(&up.true_by_source_m, &down.true_by_source_m),
                    failed: None,
                },
                Err(reason) => Sensitivity {
                    controller: family,
                    key,
                    operating_value: operating[j],
                    following: f64::NAN,
                    true_error: f64::NAN,
                    following_by_source: nan.clone(),
                    true_by_source: nan,
                    failed: Some(reason),
                },
            }
        })
        .collect()
}

fn zip(up: &[f64], down: &[f64]) -> Vec<f64> {
    up.iter()
        .zip(down)
        .map(|(&u, &d)| {
            if u > 0.0 && d > 0.0 {
                elasticity(u, d)
            } else {
                f64::NAN
            }
        })
        .collect()
}
