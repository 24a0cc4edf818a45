//! `servo identify`: the Table 5-2 parameters of the four-mass stage (m1 + m2, k2, c2, m4, k4,
//! c4) fitted to a measured open-loop FRF (DAC command → measured position, m/V, as
//! `servo frf --loop open` writes it) with the simulator's exact sampled model as the grey box
//! (delays, current loop, sensor filter known), by [`design::identify`].

mod misfit;
mod resonance;
mod site;
mod tail;

pub use misfit::{Misfit, MISFIT_MIN_RELATIVE, MISFIT_SIGMAS};
pub use site::{describe_site, place_modes, SiteEvidence};

use crate::error::StudyError;
use loop_model::closed_loop::ClosedLoop;
use num_complex::Complex64;
use plant_sim::modes::{ExtraMode, ModeSite, MAX_MODES};
use plant_sim::params::StageParams;
use plant_sim::PlantParams;
use plant_sim::Simulator;
use run_config::frf_file::MeasuredFrf;
use runner::Plan;

/// The identified parameters, in Table 5-2 order.
pub const NAMES: [&str; 6] = [
    "m1 + m2 kg",
    "k2 N/m",
    "c2 N·s/m",
    "m4 kg",
    "k4 N/m",
    "c4 N·s/m",
];

/// The lowest Durbin–Watson statistic of a residual taken as white. White noise over the
/// 2 × 150 residuals of a 150-point FRF gives 2 ± 0.12; on 30 practice stages (seeds
/// 2000–2029) the fits with every mode found gave 1.75–2.33, those lacking the mount above the
/// band 0.05–0.11.
pub const WHITE_RESIDUAL_DURBIN_WATSON: f64 = 1.5;

/// How a report opens the reason for a 1σ that includes the structure's part.
const WITH_STRUCTURE: &str =
    "1σ with the model structure's part (a delete-a-band jackknife; conservative)";

/// What an identification's 1σ rests on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UncertaintyBasis {
    /// The noise alone (a sandwich over each point's noise variance, `design::identify`): every misfit band was explained by a fitted mode and the
    /// residual is white ([`WHITE_RESIDUAL_DURBIN_WATSON`]) — the model structure is complete
    /// as far as the measurement can tell.
    Noise,
    /// The noise's part and the structure's (a delete-a-band jackknife), combined, because a
    /// band of the measurement is left unexplained (a misfit no mode explains, or points the
    /// fit with its modes leaves out): conservative.
    BandsLeftOut,
    /// The same, because the residual is smooth along frequency (Durbin–Watson below
    /// [`WHITE_RESIDUAL_DURBIN_WATSON`]): the model lacks something; conservative.
    SmoothResidual,
}

/// Table 5-2 values of a stage.
pub fn table_5_2(s: &StageParams) -> [f64; 6] {
    [
        s.m1_kg + s.m2_kg,
        s.k2_n_per_m,
        s.c2_n_s_per_m,
        s.m4_kg,
        s.k4_n_per_m,
        s.c4_n_s_per_m,
    ]
}

/// `base` with the Table 5-2 values `p` (m1 kept; m2 = `p[0]` − m1).
pub fn with_table_5_2(base: &StageParams, p: &[f64]) -> StageParams {
    StageParams {
        m2_kg: p[0] - base.m1_kg,
        k2_n_per_m: p[1],
        c2_n_s_per_m: p[2],
        m4_kg: p[3],
        k4_n_per_m: p[4],
        c4_n_s_per_m: p[5],
        ..*base
    }
}

/// The result of `servo identify`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Identified {
    /// Parameter names and units ([`NAMES`]).
    pub names: Vec<String>,
    /// Fitted values.
    pub fitted: Vec<f64>,
    /// Relative 1σ uncertainty of each (what it rests on: [`Identified::uncertainty`]).
    pub rel_std: Vec<f64>,
    /// What the 1σ rests on.
    pub uncertainty: UncertaintyBasis,
    /// The Durbin–Watson statistic of the fit's relative residual along frequency (about 2:
    /// white, the model explains the measurement to its noise; toward 0: a structure it lacks).
    pub durbin_watson: f64,
    /// The starting (configured) values.
    pub start: Vec<f64>,
    /// MATLAB-style fit % on the complex response (thesis §5.5.3: 97.7 %).
    pub fit_percent: f64,
    /// Fit % on the relative residuals (what is minimised).
    pub weighted_fit_percent: f64,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// FRF points used in the fit (the misfit bands' points are left out unless a resonance
    /// explains them).
    pub points: usize,
    /// Bands of the FRF the four-mass model alone does not explain (an unmodelled resonance, a
    /// disturbed measurement): reported rather than absorbed.
    pub misfits: Vec<Misfit>,
    /// The resonances fitted beside the stage where the misfits were (the worst bands first,
    /// as many as explain their bands and the plant has room for), then a mode above the
    /// measured band fitted to its tail when it explains more than noise: extra modes on the
    /// reading, written into the model file with the stage.
    pub extra_modes: Vec<ExtraMode>,
    /// The highest measured frequency, Hz: an extra mode above it was fitted to its tail.
    pub top_hz: f64,
    /// For each extra mode, why it is where it is (None: on the reading, as the gap's FRF
    /// cannot tell; [`place_modes`] decides from the accelerometer's).
    pub sites: Vec<Option<SiteEvidence>>,
    /// Bands the fit with those modes still cannot explain and leaves out (a point measured
    /// while the stage was changing, say); empty without modes (the misfits are left out).
    pub left_out: Vec<Misfit>,
}

impl Identified {
    /// `plan`'s plant with the fitted stage and, after the plant's own, the extra modes found.
    pub fn plant(&self, plan: &Plan) -> PlantParams {
        PlantParams {
            stage: with_table_5_2(&plan.config.plant.stage, &self.fitted),
            modes: plan.config.plant.modes.with(&self.extra_modes),
            ..plan.config.plant
        }
    }

    /// The identified plant as a run-config fragment (`servo tune --plant model.toml`, `servo synth
    /// h2 --plant model.toml`, `servo run --plant model.toml`): `plan`'s plant with the fitted stage,
    /// opened by comments saying where it came from (`source`: the FRF file and its SHA-256)
    /// and how well it fits.
    pub fn model_toml(&self, plan: &Plan, source: &str) -> String {
        let plant = self.plant(plan);
        let mut out = format!(
            "# Plant identified by `servo identify` from {source} (quantity P): fit {:.2} % on {} points\n\
             # (thesis §5.5.3: 97.7 %); the configured plant with the fitted Table 5-2 stage values:\n",
            self.fit_percent, self.points
        );
        for i in 0..self.names.len() {
            out += &format!(
                "#   {:<12} {:.5e} ± {:.2} % (1σ)\n",
                self.names[i],
                self.fitted[i],
                100.0 * self.rel_std[i]
            );
        }
        out += &format!("# {}\n", self.uncertainty_note());
        for m in &self.misfits {
            out += &format!(
                "# not explained by the four-mass model: {:.0} – {:.0} Hz ({} points, up to {:+.1} dB)\n",
                m.from_hz, m.to_hz, m.points, m.worst_db
            );
        }
        for (r, site) in self.extra_modes.iter().zip(&self.sites) {
            out += &format!(
                "# fitted beside the stage, in this model as [[plant.modes]]: {};\n\
                 #   {}\n",
                self.describe_mode(r),
                site_comment(site)
            );
        }
        let made_for = run_config::made_for_plant(&plant);
        out += &format!("# made for {}; {}\n", made_for.describe(), made_for.tool);
        out + &run_config::plant_toml(&plant)
    }

    /// What the 1σ rests on, in words (for a report and a plant file's comment).
    pub fn uncertainty_note(&self) -> String {
        match self.uncertainty {
            UncertaintyBasis::Noise => format!(
                "1σ from the noise alone: every misfit explained and the residual white (Durbin–Watson {:.2})",
                self.durbin_watson
            ),
            UncertaintyBasis::BandsLeftOut => {
                format!("{WITH_STRUCTURE}: bands of the measurement are left unexplained")
            }
            UncertaintyBasis::SmoothResidual => format!(
                "{WITH_STRUCTURE}: the residual is smooth along frequency (Durbin–Watson {:.2} < {WHITE_RESIDUAL_DURBIN_WATSON})",
                self.durbin_watson
            ),
        }
    }

    /// Extra mode `m` in words: its poles, zeros and peak, and whether it lies above the
    /// measured band (fitted to its tail: known as well as the tail shows it).
    pub fn describe_mode(&self, m: &ExtraMode) -> String {
        let mut words = format!(
            "a resonance at {:.0} Hz (ζ {:.4}), zeros at {:.0} Hz (ζ {:.4}), {:+.1} dB",
            m.hz,
            m.zeta,
            m.zero_hz,
            m.zero_zeta,
            m.peak_db()
        );
        if m.hz.min(m.zero_hz) >= self.top_hz {
            words += &format!(
                ", above the measured band (to {:.0} Hz): fitted to its tail",
                self.top_hz
            );
        }
        words
    }
}

/// Where a mode was placed and why, for a plant file's comment.
pub(crate) fn site_comment(site: &Option<SiteEvidence>) -> String {
    let described = describe_site(site);
    match site {
        Some(_) => described,
        None => described
            + " — a gap FRF alone cannot tell a sensor\n\
             #   mount from a stage mode — the designs and loop checks see them alike, the tool motion predicted\n\
             #   from the model would not",
    }
}

/// The mode of fitted parameters `p` (`[pole_hz, pole_zeta, zero_hz, zero_zeta]`), on the
/// reading: what a command → gap FRF shows of an extra mode.
pub(crate) fn sensor_mode(p: &[f64]) -> ExtraMode {
    ExtraMode {
        at: ModeSite::Sensor,
        hz: p[0],
        zeta: p[1],
        zero_hz: p[2],
        zero_zeta: p[3],
    }
}

/// [`identify`] on a measured FRF file's content, its extra modes placed by the accelerometer's
/// FRF when the file has it ([`place_modes`]).
pub fn identify_measured(plan: &Plan, frf: &MeasuredFrf) -> Result<Identified, StudyError> {
    let mut id = identify(plan, &frf.freq_hz, &frf.response)?;
    let fitted = PlantParams {
        stage: with_table_5_2(&plan.config.plant.stage, &id.fitted),
        ..plan.config.plant
    };
    id.sites = place_modes(&fitted, &mut id.extra_modes, frf)?;
    Ok(id)
}

/// Lowest fit % (on the complex response) `identify` reports as a result; below it the model
/// does not explain the data (the thesis's own fit: 97.7 %).
pub const MIN_CREDIBLE_FIT_PERCENT: f64 = 70.0;

/// The open loop of `plant` with the ideal current loop (the linear model a fit compares with).
pub(crate) fn open_model(plant: &PlantParams) -> Result<ClosedLoop, String> {
    let mut ideal = *plant;
    ideal.actuator.model = plant_sim::params::CurrentLoopModel::Ideal;
    let sim = Simulator::new(&ideal, 0, &Default::default()).map_err(|e| e.to_string())?;
    ClosedLoop::open(&sim, ideal.capa.sensitivity_v_per_m).ok_or_else(|| "no linear model".into())
}

/// The model's open-loop response (m/V) at `freq_hz` for stage `stage` in `cfg`'s plant.
pub(crate) fn open_loop(
    plan: &Plan,
    stage: StageParams,
    freq_hz: &[f64],
) -> Result<Vec<Complex64>, String> {
    let plant = PlantParams {
        stage,
        ..plan.config.plant
    };
    open_model(&plant)?
        .command_responses(freq_hz)
        .into_iter()
        .map(|r| r.map_err(|e| e.to_string()))
        .collect()
}

/// Fits the Table 5-2 parameters to `(freq_hz, measured)`, starting from `plan`'s stage, each
/// bounded to a factor 4 around its start. Points the four-mass model cannot explain are
/// found and left out (the `misfit` module); where they show a resonance, it is fitted as a factor
/// beside the stage on every point (the `resonance` module) and reported; a mode above the
/// measured band is fitted to its tail when it explains more than noise (the `tail` module).
/// The 1σ is the noise's when no band is left unexplained and the residual is white along
/// frequency ([`UncertaintyBasis`]). `freq_hz` must increase. Fails with
/// [`StudyError::FitNotCredible`] when the fit explains less than [`MIN_CREDIBLE_FIT_PERCENT`]
/// of the data.
pub fn identify(
    plan: &Plan,
    freq_hz: &[f64],
    measured: &[Complex64],
) -> Result<Identified, StudyError> {
    let base = plan.config.plant.stage;
    let start = table_5_2(&base);
    let mut lower = start.map(|v| v / 4.0);
    lower[0] = lower[0].max(1.05 * base.m1_kg);
    let upper = start.map(|v| v * 4.0);
    let stage = |p: &[f64], f: &[f64]| -> Result<Vec<Complex64>, String> {
        open_loop(plan, with_table_5_2(&base, p), f)
    };
    let invalid = |e: String| StudyError::from(design::identify::IdentifyError::Invalid(e));
    if !freq_hz.windows(2).all(|w| w[0] < w[1]) {
        return Err(invalid("the frequencies must increase".into()));
    }
    let top_hz = freq_hz.last().copied().unwrap_or(f64::NAN);
    let (f, keep, fitted) = misfit::fit_excluding(
        freq_hz,
        measured,
        run_config::frf_file::MIN_POINTS,
        |kf, km| {
            let mut model = |p: &[f64]| stage(p, kf);
            let f = design::identify::fit(&mut model, km, &start, &lower, &upper, 200)?;
            let fitted = stage(&f.params, freq_hz).map_err(invalid)?;
            Ok((f, fitted))
        },
    )?;
    // The points the stage alone was fitted on.
    let stage_kept_hz = kept(freq_hz, &keep);
    let ratio: Vec<Complex64> = (0..freq_hz.len())
        .map(|i| measured[i] / fitted[i])
        .collect();
    let misfits = misfit::misfit_bands(freq_hz, &keep, &ratio);
    // The misfit bands as resonances beside the stage, fitted with it: the worst bands first,
    // as many as the plant has room for and as explain what they cover.
    let room = MAX_MODES - plan.config.plant.modes.iter().count();
    let mut worst_first: Vec<&Misfit> = misfits.iter().collect();
    worst_first.sort_by(|a, b| b.worst_relative.total_cmp(&a.worst_relative));
    worst_first.truncate(room);
    let bounds = (&f.params[..], &lower[..], &upper[..]);
    let resonances = (1..=worst_first.len()).rev().find_map(|k| {
        let (fitted_bands, left) = worst_first.split_at(k);
        let data = (freq_hz, measured, &ratio[..]);
        with_modes(data, fitted_bands, left, None, stage, bounds).map(|w| (k, w))
    });
    let k = resonances.as_ref().map_or(0, |(k, _)| *k);
    let (fitted_bands, left) = worst_first.split_at(k);
    // A mode above the band, seen by its tail, beside them when it explains more than noise.
    let with_tail = (room > k)
        .then(|| {
            let (base, base_bounds) = match &resonances {
                Some((_, w)) => (w.fit.params.clone(), w.bounds.clone()),
                None => (f.params.clone(), (lower.to_vec(), upper.to_vec())),
            };
            let data = (freq_hz, measured, &ratio[..]);
            let bounds = (&base[..], &base_bounds.0[..], &base_bounds.1[..]);
            with_modes(data, fitted_bands, left, Some(top_hz), stage, bounds)
        })
        .flatten()
        .filter(|t| {
            let (without, kept_hz) = match &resonances {
                Some((_, w)) => (w.fit.cost, &w.kept_hz),
                None => (f.cost, &stage_kept_hz),
            };
            // Compared on the points the fit without it kept: the fit with it keeps each of them
            // (and any more only add to its cost).
            kept_hz.iter().all(|hz| t.kept_hz.contains(hz))
                && tail::explains_more_than_noise(
                    without,
                    t.fit.cost,
                    kept_hz.len(),
                    t.fit.params.len(),
                )
        });
    let (f, points, extra_modes, left_out, bands_fitted) =
        match with_tail.or(resonances.map(|(_, w)| w)) {
            Some(w) => (w.fit, w.kept_hz.len(), w.extra_modes, w.left_out, k),
            None => (f, stage_kept_hz.len(), Vec::new(), Vec::new(), 0),
        };
    let uncertainty = if bands_fitted < misfits.len() || !left_out.is_empty() {
        UncertaintyBasis::BandsLeftOut
    } else if f.durbin_watson < WHITE_RESIDUAL_DURBIN_WATSON {
        UncertaintyBasis::SmoothResidual
    } else {
        UncertaintyBasis::Noise
    };
    let rel_std = match uncertainty {
        UncertaintyBasis::Noise => &f.rel_std,
        _ => &f.rel_std_with_structure,
    };
    if f.fit_percent.is_nan() || f.fit_percent < MIN_CREDIBLE_FIT_PERCENT {
        return Err(StudyError::FitNotCredible {
            fit_percent: f.fit_percent,
        });
    }
    Ok(Identified {
        names: NAMES.iter().map(|s| s.to_string()).collect(),
        fitted: f.params[..6].to_vec(),
        rel_std: rel_std[..6].to_vec(),
        uncertainty,
        durbin_watson: f.durbin_watson,
        start: start.to_vec(),
        fit_percent: f.fit_percent,
        weighted_fit_percent: f.weighted_fit_percent,
        iterations: f.iterations,
        points,
        misfits,
        top_hz,
        sites: vec![None; extra_modes.len()],
        extra_modes,
        left_out,
    })
}

/// The stage fitted again with a resonance for each of `bands` (on the reading, from where
/// each band was) and, with `tail_above` (the top measured frequency, Hz), a mode above the band,
/// on every point but those of the misfit bands `left` unfitted, leaving out what it still
/// cannot explain (a point measured while the stage was changing, say): the fit, the points it
/// kept, the modes and the bands it left out — when each resonance stays near its band and
/// explains it (every point of the band kept). `data`: frequencies (Hz), measured responses and
/// their ratio to the stage fitted alone.
fn with_modes(
    (freq_hz, measured, ratio): (&[f64], &[Complex64], &[Complex64]),
    bands: &[&Misfit],
    left: &[&Misfit],
    tail_above: Option<f64>,
    stage: impl Fn(&[f64], &[f64]) -> Result<Vec<Complex64>, String>,
    (start, lower, upper): (&[f64], &[f64], &[f64]),
) -> Option<WithModes> {
    if ratio.is_empty() {
        return None;
    }
    let within = |f: f64, b: &Misfit| (b.from_hz..=b.to_hz).contains(&f);
    let (fu, mu): (Vec<f64>, Vec<Complex64>) = (0..freq_hz.len())
        .filter(|&i| !left.iter().any(|b| within(freq_hz[i], b)))
        .map(|i| (freq_hz[i], measured[i]))
        .unzip();
    let (mut p0, mut lo, mut hi) = (start.to_vec(), lower.to_vec(), upper.to_vec());
    // The resonances already in `start` (a fit with them) are not started again.
    for band in bands.iter().skip((start.len() - 6) / 4) {
        let worst = ratio[freq_hz.iter().position(|&x| x == band.worst_hz)?].norm();
        let (r0, rlo, rhi) = resonance::start_and_bounds(band, worst);
        p0.extend(r0);
        lo.extend(rlo);
        hi.extend(rhi);
    }
    if let Some(top_hz) = tail_above {
        let last = &ratio[ratio.len() - (ratio.len() / 6).max(1)..];
        let (t0, tlo, thi) = tail::start_and_bounds(top_hz, last);
        p0.extend(t0);
        lo.extend(tlo);
        hi.extend(thi);
    }
    // A fit ending on a bound may sit a rounding outside it.
    for i in 0..p0.len() {
        p0[i] = p0[i].clamp(lo[i], hi[i]);
    }
    let modes = |p: &[f64]| -> Vec<ExtraMode> { p[6..].chunks(4).map(sensor_mode).collect() };
    let response = |p: &[f64], f: &[f64]| -> Result<Vec<Complex64>, String> {
        let modes = modes(p);
        Ok(stage(&p[..6], f)?
            .iter()
            .zip(f)
            .map(|(g, &fq)| modes.iter().fold(*g, |g, m| g * m.response(fq)))
            .collect())
    };
    let invalid = |e: String| StudyError::from(design::identify::IdentifyError::Invalid(e));
    let (f, keep, fitted) =
        misfit::fit_excluding(&fu, &mu, run_config::frf_file::MIN_POINTS, |kf, km| {
            let mut on_kept = |p: &[f64]| response(p, kf);
            let f = design::identify::fit(&mut on_kept, km, &p0, &lo, &hi, 200)?;
            let fitted = response(&f.params, &fu).map_err(invalid)?;
            Ok((f, fitted))
        })
        .ok()?;
    let extra = modes(&f.params);
    for (m, band) in extra.iter().zip(bands) {
        resonance::plausible(m, band).ok()?;
    }
    if let (Some(top_hz), Some(m)) = (tail_above, extra.last()) {
        tail::off_its_bounds(m, top_hz).then_some(())?;
    }
    let explained = (0..fu.len()).all(|i| keep[i] || !bands.iter().any(|b| within(fu[i], b)));
    let residual: Vec<Complex64> = mu.iter().zip(&fitted).map(|(m, g)| m / g).collect();
    explained.then(|| WithModes {
        kept_hz: kept(&fu, &keep),
        left_out: misfit::misfit_bands(&fu, &keep, &residual),
        fit: f,
        extra_modes: extra,
        bounds: (lo, hi),
    })
}

/// What [`with_modes`] found.
struct WithModes {
    fit: design::identify::Fit,
    extra_modes: Vec<ExtraMode>,
    left_out: Vec<Misfit>,
    /// The parameters' bounds (stage, then four per mode).
    bounds: (Vec<f64>, Vec<f64>),
    /// The frequencies of the points kept, Hz.
    kept_hz: Vec<f64>,
}

/// The frequencies of `freq_hz` whose `keep` is set.
fn kept(freq_hz: &[f64], keep: &[bool]) -> Vec<f64> {
    (0..freq_hz.len())
        .filter(|&i| keep[i])
        .map(|i| freq_hz[i])
        .collect()
}
