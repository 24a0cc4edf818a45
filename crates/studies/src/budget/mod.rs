//! The error budget of a loop (thesis §5.7.2, eq 5-13..5-17): per-source PSDs of the
//! following error and of the true error, their CAS, and exact RMS values from the discrete
//! Lyapunov equation of the sampled closed loop.

use loop_model::closed_loop::{output, ClosedLoop, SOURCES};
use lti::spectral::cas;
use lti::{dlyap, LtiError, StateSpace};
use nalgebra::DMatrix;
use serde::Serialize;

/// One source's share of the errors.
#[derive(Debug, Clone, Serialize)]
pub struct Contribution {
    /// Source name.
    pub source: String,
    /// Its RMS following error in m.
    pub following_rms_m: f64,
    /// Its RMS true error in m.
    pub true_rms_m: f64,
}

/// The error budget of a loop (§5.7.2).
#[derive(Debug, Clone, Serialize)]
pub struct Budget {
    /// Closed-loop −3 dB bandwidth in Hz.
    pub bandwidth_hz: f64,
    /// Per-source RMS (exact: discrete Lyapunov).
    pub contributions: Vec<Contribution>,
    /// Total RMS following error in m (sources are independent: powers add, eq 5-15).
    pub following_rms_m: f64,
    /// Total RMS true error in m (eq 5-14).
    pub true_rms_m: f64,
    /// Frequency grid in Hz for the spectra.
    pub freq_hz: Vec<f64>,
    /// Following-error PSD per source, m²/Hz (one-sided), `[source][frequency]` (JSON: an
    /// object by source name).
    #[serde(rename = "following_psd_m2_per_hz", serialize_with = "by_source")]
    pub following_psd: Vec<Vec<f64>>,
    /// True-error PSD per source, m²/Hz.
    #[serde(rename = "true_psd_m2_per_hz", serialize_with = "by_source")]
    pub true_psd: Vec<Vec<f64>>,
    /// CAS of the total following error, m (eq 5-16).
    #[serde(rename = "following_cas_m")]
    pub following_cas: Vec<f64>,
    /// CAS of the total true error, m.
    #[serde(rename = "true_cas_m")]
    pub true_cas: Vec<f64>,
}

/// Per-source rows as an object keyed by the source's name ([`SOURCES`] order).
fn by_source<S: serde::Serializer>(rows: &[Vec<f64>], s: S) -> Result<S::Ok, S::Error> {
    use serde::ser::SerializeMap;
    let mut map = s.serialize_map(Some(rows.len()))?;
    for ((name, _), row) in SOURCES.iter().zip(rows) {
        map.serialize_entry(name, row)?;
    }
    map.end()
}

/// Output variance caused by one white input of per-tick variance `var`.
fn variance(sys: &StateSpace, out: usize, inp: usize, var: f64) -> Result<f64, LtiError> {
    if var == 0.0 {
        return Ok(0.0);
    }
    let b = sys.b.column(inp);
    let (p, _) = dlyap(&sys.a, &(b * b.transpose() * var))?;
    let c = sys.c.row(out);
    let d = sys.d[(out, inp)];
    Ok((c * p * c.transpose())[(0, 0)] + d * d * var)
}

/// The PSD of all sources together, `per_source[source][frequency]` summed over the sources
/// (they are independent: powers add, eq 5-15).
pub fn total_psd(per_source: &[Vec<f64>]) -> Vec<f64> {
    let n = per_source.first().map_or(0, Vec::len);
    (0..n)
        .map(|i| per_source.iter().map(|p| p[i]).sum())
        .collect()
}

/// One-sided PSD at `freq_hz` of each of `outputs` (one of [`output`]) caused by each noise
/// source of [`SOURCES`], `[output][source][frequency]`, in the output's unit²/Hz (a white
/// per-tick variance σ² is a one-sided input PSD of 2σ²/fs).
pub fn source_psds<const N: usize>(
    cl: &ClosedLoop,
    freq_hz: &[f64],
    outputs: [usize; N],
) -> Result<[Vec<Vec<f64>>; N], LtiError> {
    let fs = 1.0 / cl.period_s;
    let response = lti::FrequencyResponse::new(&cl.sys);
    let responses: Vec<DMatrix<num_complex::Complex64>> = freq_hz
        .iter()
        .map(|&f| response.discrete(f, cl.period_s))
        .collect::<Result<_, _>>()?;
    Ok(outputs.map(|out| {
        SOURCES
            .iter()
            .enumerate()
            .map(|(k, (_, inp))| {
                let scale = 2.0 * cl.noise_variance[k] / fs;
                responses
                    .iter()
                    .map(|h| h[(out, *inp)].norm_sqr() * scale)
                    .collect()
            })
            .collect()
    }))
}

impl Budget {
    /// The budget of `cl` on a log grid of `points` frequencies from 1 Hz to Nyquist.
    pub fn new(cl: &ClosedLoop, points: usize) -> Result<Self, LtiError> {
        let nyquist = 0.5 / cl.period_s;
        let freq_hz = lti::spectral::log_space(1.0, nyquist, points);
        let [following_psd, true_psd] = source_psds(
            cl,
            &freq_hz,
            [output::FOLLOWING_ERROR_M, output::TRUE_ERROR_M],
        )?;
        let contributions = SOURCES
            .iter()
            .enumerate()
            .map(|(k, (name, inp))| {
                let var = cl.noise_variance[k];
                Ok(Contribution {
                    source: name.to_string(),
                    following_rms_m: variance(&cl.sys, output::FOLLOWING_ERROR_M, *inp, var)?
                        .sqrt(),
                    true_rms_m: variance(&cl.sys, output::TRUE_ERROR_M, *inp, var)?.sqrt(),
                })
            })
            .collect::<Result<Vec<_>, LtiError>>()?;
        let following_cas = cas(&freq_hz, &total_psd(&following_psd));
        let true_cas = cas(&freq_hz, &total_psd(&true_psd));
        let rss = |f: fn(&Contribution) -> f64| {
            contributions
                .iter()
                .map(|c| f(c).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        Ok(Budget {
            bandwidth_hz: cl.bandwidth_hz()?,
            following_rms_m: rss(|c| c.following_rms_m),
            true_rms_m: rss(|c| c.true_rms_m),
            contributions,
            freq_hz,
            following_psd,
            true_psd,
            following_cas,
            true_cas,
        })
    }
}

/// The error budget of a plan's loop with what it is reported with: what `servo budget` and
/// `fts_servo.budget` compute — one function, so both print the same numbers.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Analysis {
    /// The budget.
    pub budget: Budget,
    /// The loop's margins broken at the DAC (None for a plant without an exact sampled model:
    /// the `coil` current loop).
    pub margins: Option<design::loops::Margins>,
    /// `controller, stage mass` for titles.
    pub title: String,
    /// The plant and rate it was computed for.
    pub made_for: run_config::MadeFor,
}

/// The budget of `plan`'s loop on `points` log-spaced frequencies (at least 16), with its
/// margins; refused when the loop is unstable.
pub fn analyse(plan: &runner::Plan, points: usize) -> Result<Analysis, crate::StudyError> {
    plan.check_stable()?;
    let budget = Budget::new(&plan.closed_loop, points.max(16))?;
    let stage = &plan.config.plant.stage;
    Ok(Analysis {
        budget,
        margins: crate::margins::loop_margins(plan).ok(),
        title: format!(
            "{}, {:.3} kg stage",
            plan.controller.description,
            stage.m1_kg + stage.m2_kg
        ),
        made_for: run_config::made_for_plant(&plan.config.plant),
    })
}
