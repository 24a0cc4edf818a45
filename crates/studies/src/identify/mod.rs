//! `servo identify`: the Table 5-2 parameters of the four-mass stage (m1 + m2, k2, c2, m4, k4,
//! c4) fitted to a measured open-loop FRF (DAC command → measured position, m/V, as
//! `servo frf --loop open` writes it) with the simulator's exact sampled model as the grey box
//! (delays, current loop, sensor filter known), by [`design::identify`].

mod misfit;
mod resonance;

pub use misfit::{Misfit, MISFIT_MIN_RELATIVE, MISFIT_SIGMAS};

use crate::error::StudyError;
use num_complex::Complex64;
use plant_sim::modes::{ExtraMode, ModeSite};
use plant_sim::params::StageParams;
use plant_sim::PlantParams;
use plant_sim::Simulator;
use runner::closed_loop::ClosedLoop;
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
    /// Relative 1σ uncertainty of each.
    pub rel_std: Vec<f64>,
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
    /// The resonance fitted beside the stage where the worst misfit was, when it explains
    /// it: an extra mode on the reading, written into the model file with the stage.
    pub extra_mode: Option<ExtraMode>,
}

impl Identified {
    /// `plan`'s plant with the fitted stage and, after the plant's own, the extra mode found
    /// (when there is room for it).
    pub fn plant(&self, plan: &Plan) -> PlantParams {
        PlantParams {
            stage: with_table_5_2(&plan.config.plant.stage, &self.fitted),
            modes: plan.config.plant.modes.with(&self.extra_mode),
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
        for m in &self.misfits {
            out += &format!(
                "# not explained by the four-mass model: {:.0} – {:.0} Hz ({} points, up to {:+.1} dB)\n",
                m.from_hz, m.to_hz, m.points, m.worst_db
            );
        }
        if let Some(r) = &self.extra_mode {
            let place = if plant.modes.iter().any(|m| m == r) {
                "in this model as [[plant.modes]]"
            } else {
                "NOT in this model (the configured plant already carries the most extra modes)"
            };
            out += &format!(
                "# fitted beside the stage, {place}: a resonance at {:.0} Hz (ζ {:.4}), zeros at {:.0} Hz (ζ {:.4}), {:+.1} dB;\n\
                 #   on the reading (at = \"sensor\"): this FRF cannot tell a sensor mount from a stage mode — the designs and\n\
                 #   loop checks see them alike, the tool motion predicted from the model would not\n",
                r.hz, r.zeta, r.zero_hz, r.zero_zeta, r.peak_db()
            );
        }
        let made_for = run_config::made_for_plant(&plant);
        out += &format!("# made for {}; {}\n", made_for.describe(), made_for.tool);
        out + &run_config::plant_toml(&plant)
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

/// Lowest fit % (on the complex response) `identify` reports as a result; below it the model
/// does not explain the data (the thesis's own fit: 97.7 %).
pub const MIN_CREDIBLE_FIT_PERCENT: f64 = 70.0;

/// The model's open-loop response (m/V) at `freq_hz` for stage `stage` in `cfg`'s plant.
pub(crate) fn open_loop(
    plan: &Plan,
    stage: StageParams,
    freq_hz: &[f64],
) -> Result<Vec<Complex64>, String> {
    let mut plant = plan.config.plant;
    plant.stage = stage;
    plant.actuator.model = plant_sim::params::CurrentLoopModel::Ideal;
    let sim = Simulator::new(&plant, 0, &Default::default()).map_err(|e| e.to_string())?;
    let open = ClosedLoop::open(&sim, plant.capa.sensitivity_v_per_m).ok_or("no linear model")?;
    open.command_responses(freq_hz)
        .into_iter()
        .map(|r| r.map_err(|e| e.to_string()))
        .collect()
}

/// Fits the Table 5-2 parameters to `(freq_hz, measured)`, starting from `plan`'s stage, each
/// bounded to a factor 4 around its start. Points the four-mass model cannot explain are
/// found and left out (the `misfit` module); where they show a resonance, it is fitted as a factor
/// beside the stage on every point (the `resonance` module) and reported. Fails with
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
    let ratio: Vec<Complex64> = (0..freq_hz.len())
        .map(|i| measured[i] / fitted[i])
        .collect();
    let misfits = misfit::misfit_bands(freq_hz, &keep, &ratio);
    // The worst misfit band as a resonance beside the stage, on every point: kept when it
    // explains the band (no misfit left) from where the band was.
    let with_resonance = misfits
        .iter()
        .max_by(|a, b| a.worst_relative.total_cmp(&b.worst_relative))
        .and_then(|band| {
            let worst = ratio[freq_hz.iter().position(|&x| x == band.worst_hz)?].norm();
            let (r0, rlo, rhi) = resonance::start_and_bounds(band, worst);
            let cat = |a: &[f64], b: [f64; 4]| [a, &b[..]].concat();
            let mut model = |p: &[f64]| {
                let g = stage(&p[..6], freq_hz)?;
                Ok(g.iter()
                    .zip(freq_hz)
                    .map(|(g, &fq)| g * sensor_mode(&p[6..]).response(fq))
                    .collect())
            };
            let f = design::identify::fit(
                &mut model,
                measured,
                &cat(&f.params, r0),
                &cat(&lower, rlo),
                &cat(&upper, rhi),
                200,
            )
            .ok()?;
            let extra = sensor_mode(&f.params[6..]);
            resonance::plausible(&extra, band).ok()?;
            let fitted = model(&f.params).ok()?;
            let all = vec![true; freq_hz.len()];
            let explained =
                misfit::kept_after(&misfit::relative_residuals(measured, &fitted), &all)
                    .iter()
                    .all(|k| *k);
            explained.then_some((f, extra))
        });
    let (f, points, extra_mode) = match with_resonance {
        Some((f, extra)) => (f, freq_hz.len(), Some(extra)),
        None => (f, keep.iter().filter(|k| **k).count(), None),
    };
    if f.fit_percent.is_nan() || f.fit_percent < MIN_CREDIBLE_FIT_PERCENT {
        return Err(StudyError::FitNotCredible {
            fit_percent: f.fit_percent,
        });
    }
    Ok(Identified {
        names: NAMES.iter().map(|s| s.to_string()).collect(),
        fitted: f.params[..6].to_vec(),
        rel_std: f.rel_std[..6].to_vec(),
        start: start.to_vec(),
        fit_percent: f.fit_percent,
        weighted_fit_percent: f.weighted_fit_percent,
        iterations: f.iterations,
        points,
        misfits,
        extra_mode,
    })
}
