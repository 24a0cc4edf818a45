//! `servo fit`: a stable rational model of a measured open-loop FRF of any order
//! ([`lti::vector_fit`], z-domain vector fitting weighted by each bin's uncertainty), its order
//! the smallest whose residual is the measurement's noise — a model as good as the
//! measurement, no better (that would be fitting the noise). Its
//! resonances are set beside the plant model's: a lightly damped mode the model lacks is named
//! an extra mode, fitted onto the model as a [`plant_sim::modes::ExtraMode`] and written into
//! the plant file every design and the simulator take.

use crate::error::StudyError;
use crate::identify::{open_loop, sensor_mode};
use lti::vector_fit::{vector_fit, Mode, RationalFit};
use num_complex::Complex64;
use plant_sim::modes::ExtraMode;
use plant_sim::PlantParams;
use run_config::frf_file::MeasuredFrf;
use runner::Plan;

/// The radius, in units of a bin's 1σ (63 %) disk, of its 95 % disk: a complex Gaussian error
/// lies within `r·σ` with probability `1 − exp(−r²)`, and `√ln 20` gives 0.95.
pub const DISK_95: f64 = 1.730_818_732_290_453_6;
/// Largest order the order search tries by default.
pub const DEFAULT_MAX_ORDER: usize = 30;
/// Pole relocations per fit.
const ITERATIONS: usize = 40;
/// A fitted mode damped less than this is a resonance (compared with the model's).
const RESONANCE_ZETA: f64 = 0.2;
/// A resonance within this relative distance of a model mode's frequency is that mode.
const SAME_MODE: f64 = 0.05;
/// An extra resonance must change the response by this many of its bins' 1σ radii.
const SIGNIFICANT_SIGMAS: f64 = 5.0;

/// How the order was chosen.
#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct OrderTried {
    /// Poles.
    pub order: usize,
    /// Share of bins within their 95 % disk.
    pub within: f64,
    /// `√(mean |e/σ|²)`: 1 for a fit as close as the measurement's noise.
    pub weighted_rms: f64,
}

/// A resonance of the fit, and what the model says of it.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Resonance {
    /// Frequency, Hz.
    pub hz: f64,
    /// Damping ratio.
    pub zeta: f64,
    /// The model's mode at that frequency (`stage` or `extra mode`), or `None`: one the model
    /// lacks.
    pub in_model: Option<String>,
}

/// The result of `servo fit`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FrfFit {
    /// The order chosen (poles).
    pub order: usize,
    /// Share of bins within their 95 % disk (0.95 for a fit as close as the measurement's
    /// noise).
    pub within: f64,
    /// `√(mean |e/σ|²)` of the chosen fit.
    pub weighted_rms: f64,
    /// Every order tried, in order.
    pub tried: Vec<OrderTried>,
    /// The fit's resonances in the measured band, each set beside the model.
    pub resonances: Vec<Resonance>,
    /// The resonances the model lacks, fitted onto the model as extra modes: on the motor
    /// force or on the reading by the accelerometer's FRF when the file has it, else on the
    /// reading.
    pub extra_modes: Vec<ExtraMode>,
    /// For each extra mode, why it is where it is (None: no accelerometer FRF).
    pub sites: Vec<Option<crate::identify::SiteEvidence>>,
    /// The rational model (as `{period_s, direct_m_per_v, poles_z, residues_m_per_v}`, each
    /// complex number as `[re, im]`).
    #[serde(serialize_with = "rational")]
    pub fit: RationalFit,
}

/// A rational fit as data: its period, direct term, and each pole (in z) and residue (m/V) as
/// `[re, im]`.
fn rational<S: serde::Serializer>(fit: &RationalFit, s: S) -> Result<S::Ok, S::Error> {
    #[derive(serde::Serialize)]
    struct Rational {
        period_s: f64,
        direct_m_per_v: f64,
        poles_z: Vec<[f64; 2]>,
        residues_m_per_v: Vec<[f64; 2]>,
    }
    let pair = |c: &Complex64| [c.re, c.im];
    serde::Serialize::serialize(
        &Rational {
            period_s: fit.period_s,
            direct_m_per_v: fit.direct,
            poles_z: fit.poles.iter().map(pair).collect(),
            residues_m_per_v: fit.residues.iter().map(pair).collect(),
        },
        s,
    )
}

/// Each bin's 1σ radius: the file's uncertainty, at least 1e-6 of the response.
fn sigmas(frf: &MeasuredFrf) -> Result<Vec<f64>, StudyError> {
    let u = frf.uncertainty.as_ref().ok_or_else(|| {
        StudyError::Identification(design::identify::IdentifyError::Invalid(format!(
            "{}: no `uncertainty_m_per_v` column: a fit is weighted and judged by each bin's uncertainty (servo frf measures it)",
            frf.source
        )))
    })?;
    Ok(u.iter()
        .zip(&frf.response)
        .map(|(u, h)| u.max(1e-6 * h.norm()))
        .collect())
}

/// How `fit` agrees with `frf` within `sigma`.
fn judge(fit: &RationalFit, frf: &MeasuredFrf, sigma: &[f64]) -> OrderTried {
    let e: Vec<f64> = (0..frf.freq_hz.len())
        .map(|k| (fit.response(frf.freq_hz[k]) - frf.response[k]).norm() / sigma[k])
        .collect();
    let n = e.len() as f64;
    OrderTried {
        order: fit.order(),
        within: e.iter().filter(|&&x| x <= DISK_95).count() as f64 / n,
        weighted_rms: libm::sqrt(e.iter().map(|x| x * x).sum::<f64>() / n),
    }
}

/// Fits `frf` (its uncertainty as weights): of `order` poles when given, else the smallest
/// order up to `max_order` whose weighted residual is that of the measurement's noise (mean
/// `|e/σ|²` within two standard deviations of 1), or the closest tried; names its resonances
/// against `plan`'s plant model and fits the ones it lacks onto it.
pub fn fit_frf(
    plan: &Plan,
    frf: &MeasuredFrf,
    order: Option<usize>,
    max_order: usize,
) -> Result<FrfFit, StudyError> {
    let period = plan.config.plant.period_s();
    let sigma = sigmas(frf)?;
    let weight: Vec<f64> = sigma.iter().map(|s| 1.0 / s).collect();
    let fit_of = |n: usize| vector_fit(&frf.freq_hz, &frf.response, &weight, period, n, ITERATIONS);
    // With the right model each |e/σ|² is a unit exponential variable: their mean is 1 within
    // 1/√N (one standard deviation); a fit this close is as good as the measurement.
    let as_good_as_noise = libm::sqrt(1.0 + 2.0 / libm::sqrt(frf.freq_hz.len() as f64));
    let mut tried = Vec::new();
    let mut best: Option<(RationalFit, OrderTried)> = None;
    let orders: Vec<usize> = match order {
        Some(n) => vec![n],
        None => (2..=max_order.clamp(2, lti::vector_fit::MAX_ORDER)).collect(),
    };
    for n in orders {
        let Ok(fit) = fit_of(n) else { continue };
        let judged = judge(&fit, frf, &sigma);
        tried.push(judged);
        let better = best
            .as_ref()
            .is_none_or(|(_, b)| judged.weighted_rms < b.weighted_rms);
        if better {
            best = Some((fit, judged));
        }
        if judged.weighted_rms <= as_good_as_noise {
            break;
        }
    }
    let (fit, chosen) = best.ok_or(StudyError::Model(lti::LtiError::Argument(
        "vector fit: no order could be fitted",
    )))?;
    let resonances = resonances(&fit, frf, &plan.config.plant);
    let lacking: Vec<&Resonance> = resonances.iter().filter(|r| r.in_model.is_none()).collect();
    let mut extra_modes = extra_modes(plan, frf, &sigma, &lacking)?;
    let sites = crate::identify::place_modes(&plan.config.plant, &mut extra_modes, frf)?;
    Ok(FrfFit {
        sites,
        order: chosen.order,
        within: chosen.within,
        weighted_rms: chosen.weighted_rms,
        tried,
        resonances,
        extra_modes,
        fit,
    })
}

/// The model's lightly damped modes: the four-mass mechanics' and the plant's extra modes.
fn model_modes(plant: &PlantParams) -> Vec<(f64, String)> {
    let mech = plant_sim::model::mechanics(&plant.stage);
    let mut modes: Vec<(f64, String)> = lti::eigenvalues(&mech.a)
        .into_iter()
        .filter(|p| p.im > 0.0)
        .map(|p| {
            (
                p.norm() / (2.0 * std::f64::consts::PI),
                "stage mode".to_owned(),
            )
        })
        .collect();
    modes.extend(
        plant
            .modes
            .iter()
            .map(|m| (m.hz, format!("extra mode at {:.0} Hz", m.hz))),
    );
    modes
}

/// The fit's resonances inside the measured band, each with the model's mode it is, if any.
fn resonances(fit: &RationalFit, frf: &MeasuredFrf, plant: &PlantParams) -> Vec<Resonance> {
    let (lo, hi) = (frf.freq_hz[0], frf.freq_hz[frf.freq_hz.len() - 1]);
    let model = model_modes(plant);
    fit.modes()
        .into_iter()
        .filter(|m: &Mode| m.zeta < RESONANCE_ZETA && m.hz >= lo && m.hz <= hi)
        .map(|m| Resonance {
            hz: m.hz,
            zeta: m.zeta,
            in_model: model
                .iter()
                .find(|(hz, _)| (m.hz / hz - 1.0).abs() < SAME_MODE)
                .map(|(_, name)| name.clone()),
        })
        .collect()
}

/// The resonances `candidates` fitted onto `plan`'s model together, as extra modes on the
/// reading: pole and zero pairs by Levenberg–Marquardt on every bin, from the vector fit's
/// poles. A mode that does not move the response by more than [`SIGNIFICANT_SIGMAS`] of a
/// bin's radius `sigma` anywhere (a pole the fit set beside a zero to follow noise) is dropped
/// and the rest refitted.
fn extra_modes(
    plan: &Plan,
    frf: &MeasuredFrf,
    sigma: &[f64],
    candidates: &[&Resonance],
) -> Result<Vec<ExtraMode>, StudyError> {
    let f = &frf.freq_hz;
    let model = open_loop(plan, plan.config.plant.stage, f)
        .map_err(|e| StudyError::from(design::identify::IdentifyError::Invalid(e)))?;
    let modes = |p: &[f64]| -> Vec<ExtraMode> { p.chunks(4).map(sensor_mode).collect() };
    let with = |modes: &[ExtraMode]| -> Vec<Complex64> {
        model
            .iter()
            .zip(f)
            .map(|(g, &fq)| g * modes.iter().map(|m| m.response(fq)).product::<Complex64>())
            .collect()
    };
    let mut kept: Vec<&Resonance> = candidates.to_vec();
    loop {
        if kept.is_empty() {
            return Ok(Vec::new());
        }
        // Start: zeros at the pole, damped so that the peak matches the measured-over-model
        // ratio at the nearest bin.
        let (mut start, mut lower, mut upper) = (Vec::new(), Vec::new(), Vec::new());
        for r in &kept {
            let k = (0..f.len())
                .min_by(|&a, &b| (f[a] - r.hz).abs().total_cmp(&(f[b] - r.hz).abs()))
                .unwrap_or(0);
            let ratio = (frf.response[k] / model[k]).norm();
            let zeta = r.zeta.clamp(1e-3, 0.19);
            start.extend([r.hz, zeta, r.hz, (zeta * ratio).clamp(1e-3, 0.7)]);
            lower.extend([r.hz / 1.2, 1e-3, r.hz / 1.5, 1e-3]);
            upper.extend([r.hz * 1.2, 0.7, r.hz * 1.5, 0.7]);
        }
        let mut predict = |p: &[f64]| -> Result<Vec<Complex64>, String> { Ok(with(&modes(p))) };
        let fitted =
            design::identify::fit(&mut predict, &frf.response, &start, &lower, &upper, 200)?;
        let all = modes(&fitted.params);
        // Each mode's own effect: the response with the others, with and without it.
        let moves: Vec<bool> = (0..all.len())
            .map(|i| {
                let others: Vec<ExtraMode> =
                    (0..all.len()).filter(|&j| j != i).map(|j| all[j]).collect();
                let without = with(&others);
                (0..f.len()).any(|k| {
                    (without[k] * (all[i].response(f[k]) - 1.0)).norm()
                        > SIGNIFICANT_SIGMAS * sigma[k]
                })
            })
            .collect();
        if moves.iter().all(|m| *m) {
            return Ok(all);
        }
        kept = kept
            .into_iter()
            .zip(&moves)
            .filter(|(_, m)| **m)
            .map(|(r, _)| r)
            .collect();
    }
}

impl FrfFit {
    /// `plan`'s plant with the extra modes appended to its own (as many as fit).
    pub fn plant(&self, plan: &Plan) -> PlantParams {
        PlantParams {
            modes: plan.config.plant.modes.with(&self.extra_modes),
            ..plan.config.plant
        }
    }

    /// The fitted plant as a run-config fragment, opened by comments saying where it came from
    /// (`source`: the FRF file and its SHA-256), the fit's order and agreement, and each mode.
    pub fn model_toml(&self, plan: &Plan, source: &str) -> String {
        let plant = self.plant(plan);
        let mut out = format!(
            "# Plant fitted by `servo fit` from {source}: a rational fit of order {} holds {:.1} % of the bins\n\
             # within their 95 % disk (weighted RMS {:.2}); the configured plant with the modes it lacks:\n",
            self.order,
            100.0 * self.within,
            self.weighted_rms
        );
        for r in &self.resonances {
            out += &format!(
                "#   resonance {:>8.1} Hz, ζ {:.4}: {}\n",
                r.hz,
                r.zeta,
                r.in_model.as_deref().unwrap_or("NOT in the model")
            );
        }
        for (m, site) in self.extra_modes.iter().zip(&self.sites) {
            let place = if plant.modes.iter().any(|x| x == m) {
                "added as [[plant.modes]]"
            } else {
                "NOT added (the plant already carries the most extra modes)"
            };
            out += &format!(
                "# extra mode {:.0} Hz (ζ {:.4}), zeros {:.0} Hz (ζ {:.4}), {:+.1} dB: {place},\n#   {}\n",
                m.hz,
                m.zeta,
                m.zero_hz,
                m.zero_zeta,
                m.peak_db(),
                crate::identify::site_comment(site)
            );
        }
        let made_for = run_config::made_for_plant(&plant);
        out += &format!("# made for {}; {}\n", made_for.describe(), made_for.tool);
        out + &run_config::plant_toml(&plant)
    }
}
