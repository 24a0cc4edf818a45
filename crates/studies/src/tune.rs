//! `servo tune`: the PID of eq 7-8 tuned on the simulator's exact sampled plant (transport
//! delay, hold, ADC averaging, sensor filter all included) by [`design::tune`] — maximal
//! integral gain under sensitivity peaks `Ms`, `Mt` and a closed-loop bandwidth — and compared with
//! the thesis Chapter 7 gains on the same plant.

use crate::budget::Budget;
use crate::error::StudyError;
use design::tune::{PidTuned, PidTuning};
use loop_model::closed_loop::ClosedLoop;
use loop_model::controller::dm;
use lti::StateSpace;
use nalgebra::DMatrix;
use num_complex::Complex64;
use run_config::PidGains;
use runner::Plan;
use servo_core::PidConfig;

/// How a PID does on the sampled loop (independent of how it was found).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PidReport {
    /// Gains `kp` (V/V), `ki` (1/s), `kd` (s).
    pub kp: f64,
    /// Integral gain, 1/s.
    pub ki: f64,
    /// Derivative gain, s.
    pub kd: f64,
    /// Largest `|S|` on a fine grid (1 Hz to Nyquist, 4000 points).
    pub max_sensitivity: f64,
    /// Largest `|T|` on the same grid.
    pub max_complementary: f64,
    /// Loop-gain crossover (the highest frequency with `|L| ≥ 1`), Hz.
    pub crossover_hz: f64,
    /// Closed-loop (−3 dB of T) bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Predicted RMS following error, m (error budget).
    pub following_rms_m: f64,
    /// Predicted RMS true tool error, m.
    pub true_rms_m: f64,
    /// Closed-loop spectral radius.
    pub spectral_radius: f64,
}

/// The result of `servo tune`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TuneReport {
    /// Target sensitivity peak.
    pub ms: f64,
    /// Target complementary sensitivity peak.
    pub mt: f64,
    /// Target loop-gain crossover, Hz.
    pub bandwidth_target_hz: f64,
    /// Linear programs solved.
    pub iterations: usize,
    /// The tuned PID.
    pub tuned: PidReport,
    /// The configured (thesis Chapter 7 by default) PID on the same plant.
    pub reference: PidReport,
    /// The tuned gains (`[controller.pid]` of a run config).
    pub pid: PidGains,
    /// The plant and rate they were tuned for.
    pub made_for: run_config::MadeFor,
    /// The offline check of the fragment's loop (a PID with these gains on this plant): the
    /// output scales a running loop that loads it may take.
    pub stability: servo_config::Stability,
    /// The plant they were tuned for (written into the fragment, so `servo run -c` runs it).
    #[serde(skip)]
    pub plant: plant_sim::PlantParams,
}

impl TuneReport {
    /// A run config fragment with the tuned gains: `servo run -c FILE` runs them.
    pub fn to_toml(&self) -> String {
        let p = &self.pid;
        format!(
            "# PID tuned by `servo tune` for |S| <= {}, |T| <= {}, |T| >= -3 dB at {} Hz:\n\
             # max|S| {:.3}, closed-loop bandwidth {:.0} Hz, predicted RMS following {:.3} nm / true {:.3} nm.\n\
             # The fragment carries the plant the gains were tuned for: `servo run -c FILE` runs on\n\
             # it, and a run on another plant or rate refuses the gains (controller.made_for).\n\
             [controller.pid]\nkp = {:e}\nki = {:e}\nkd = {:e}\ntf_s = {:e}\n\n{}\n{}\n{}",
            self.ms,
            self.mt,
            self.bandwidth_target_hz,
            self.tuned.max_sensitivity,
            self.tuned.bandwidth_hz,
            self.tuned.following_rms_m * 1e9,
            self.tuned.true_rms_m * 1e9,
            p.kp,
            p.ki,
            p.kd,
            p.tf_s,
            self.made_for.to_toml("controller.made_for"),
            servo_config::stability_toml("controller.stability", &self.stability),
            run_config::plant_toml(&self.plant)
        )
    }
}

fn with_gains(plan: &Plan, k: [f64; 3]) -> Result<Plan, StudyError> {
    let mut c = plan.config.controller.clone();
    (c.pid.kp, c.pid.ki, c.pid.kd) = (k[0], k[1], k[2]);
    Ok(plan.with_controller(c)?)
}

/// The sampled plant: DAC command (V) → gap reading (V), at `freq_hz`.
pub(crate) fn plant_response(plan: &Plan, freq_hz: &[f64]) -> Result<Vec<Complex64>, StudyError> {
    let s = plan.config.plant.capa.sensitivity_v_per_m;
    let open =
        ClosedLoop::open(&plan.sim, s).ok_or(StudyError::NeedsLinearPlant { what: "tuning" })?;
    Ok(open
        .command_responses(freq_hz)
        .into_iter()
        .map(|r| r.unwrap_or_default() * s)
        .collect())
}

/// The discrete PID's response per unit gain (`kp`, `ki`, `kd`) with derivative filter `tf_s`
/// (s) at the run's period.
pub(crate) fn pid_basis(
    plan: &Plan,
    freq_hz: &[f64],
    tf_s: f64,
) -> Result<Vec<[Complex64; 3]>, StudyError> {
    let c = &plan.config;
    let period = c.plant.period_s();
    let unit = |j: usize| -> Result<StateSpace, StudyError> {
        let mut g = [0.0; 3];
        g[j] = 1.0;
        let pid = PidConfig {
            kp: g[0],
            ki: g[1],
            kd: g[2],
            tf_s,
            limits: servo_core::Limits::UNLIMITED,
        }
        .try_build(period)
        .map_err(|e| plan.origin.invalid("controller.pid.tf_s", e, "> 0 s"))?;
        let (a, b, cc, d) = pid.coeffs().realization();
        Ok(StateSpace {
            a: dm(&a),
            b: dm(&b),
            c: dm(&cc),
            d: DMatrix::from_element(1, 1, d),
        })
    };
    let units = [unit(0)?, unit(1)?, unit(2)?].map(|u| lti::FrequencyResponse::new(&u));
    Ok(freq_hz
        .iter()
        .map(|&f| {
            let r = |j: usize| {
                units[j]
                    .discrete(f, period)
                    .map(|m| m[(0, 0)])
                    .unwrap_or_default()
            };
            [r(0), r(1), r(2)]
        })
        .collect())
}

/// Evaluates gains `k` on the sampled loop of `plan`.
fn report(plan: &Plan, k: [f64; 3], fine: &PidTuning) -> Result<PidReport, StudyError> {
    let cl = with_gains(plan, k)?.closed_loop;
    let budget = Budget::new(&cl, 400)?;
    let (max_s, max_t, _) = fine.evaluate(&k);
    let crossover_hz = fine
        .freq_hz
        .iter()
        .enumerate()
        .rev()
        .find(|&(i, _)| fine.loop_gain(i, &k).norm() >= 1.0)
        .map_or(f64::NAN, |(_, &f)| f);
    Ok(PidReport {
        kp: k[0],
        ki: k[1],
        kd: k[2],
        max_sensitivity: max_s,
        max_complementary: max_t,
        crossover_hz,
        bandwidth_hz: budget.bandwidth_hz,
        following_rms_m: budget.following_rms_m,
        true_rms_m: budget.true_rms_m,
        spectral_radius: cl.spectral_radius(),
    })
}

/// Tunes the PID of `plan`: largest `ki` with `|S| ≤ ms`, `|T| ≤ mt` and `|T| ≥ −3 dB` at
/// `bandwidth_hz`.
pub fn tune(plan: &Plan, bandwidth_hz: f64, ms: f64, mt: f64) -> Result<TuneReport, StudyError> {
    for (key, v) in [("ms", ms), ("mt", mt)] {
        if !(v > 1.0 && v < 10.0) {
            return Err(plan.origin.invalid(key, v, "1 < M < 10").into());
        }
    }
    let fs = plan.config.plant.timing.servo_rate_hz;
    if !(bandwidth_hz > 0.0 && bandwidth_hz < 0.25 * fs) {
        return Err(plan
            .origin
            .invalid("bandwidth_hz", bandwidth_hz, "0 < f < servo rate / 4")
            .into());
    }
    let problem = |points: usize| -> Result<PidTuning, StudyError> {
        let freq_hz = lti::spectral::log_space(1.0, 0.499 * fs, points);
        let p = &plan.config.controller.pid;
        Ok(PidTuning {
            plant: plant_response(plan, &freq_hz)?,
            basis: pid_basis(plan, &freq_hz, p.tf_s)?,
            freq_hz,
            ms,
            mt,
            bandwidth_hz,
            upper: [20.0 * p.kp, 20.0 * p.ki, 20.0 * p.kd],
        })
    };
    let coarse = problem(600)?;
    let fine = problem(4000)?;
    let p = &plan.config.controller.pid;
    let thesis = [p.kp, p.ki, p.kd];
    // Start: the configured PID scaled down until it is stable and inside the Ms bound.
    let start = (0..60)
        .map(|i| 0.85f64.powi(i))
        .map(|a| thesis.map(|g| g * a))
        .find(|k| {
            let (s, t, _) = coarse.evaluate(k);
            s <= ms
                && t <= mt
                && with_gains(plan, *k)
                    .map(|p| p.closed_loop.spectral_radius() < 1.0)
                    .unwrap_or(false)
        })
        .ok_or(StudyError::NoTuningStart { ms, mt })?;
    let PidTuned {
        gains, iterations, ..
    } = coarse.solve(start, 200)?;
    let tuned = report(plan, gains, &fine)?;
    let reference = report(plan, thesis, &fine)?;
    // What the fragment describes when a running loop loads it: a PID with these gains.
    let pid = PidGains {
        kp: gains[0],
        ki: gains[1],
        kd: gains[2],
        tf_s: plan.config.controller.pid.tf_s,
    };
    let fragment = plan.with_controller(run_config::ControllerConfig {
        pid,
        feedforward: plan.config.controller.feedforward,
        smoothing_hz: plan.config.controller.smoothing_hz,
        ..Default::default()
    })?;
    let stability = runner::gain_range::gain_range(&fragment)?;
    Ok(TuneReport {
        ms,
        mt,
        bandwidth_target_hz: bandwidth_hz,
        iterations,
        tuned,
        reference,
        pid,
        made_for: run_config::made_for_plant(&plan.config.plant),
        stability,
        plant: plan.config.plant,
    })
}
