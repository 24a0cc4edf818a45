//! `servo tune`: the PID of eq 7-8 tuned on the simulator's exact sampled plant (transport
//! delay, hold, ADC averaging, sensor filter all included) by [`design::tune`] — maximal
//! integral gain under sensitivity peaks `Ms`, `Mt` and a closed-loop bandwidth — and compared with
//! the thesis Chapter 7 gains on the same plant.

use crate::analysis::{Budget, ClosedLoop};
use crate::config::{Loaded, PidGains};
use crate::controller::dm;
use crate::run::{closed_loop, plant_error, RunError};
use design::lti::StateSpace;
use design::tune::{PidTuned, PidTuning};
use nalgebra::DMatrix;
use num_complex::Complex64;
use plant_sim::Simulator;
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
}

impl TuneReport {
    /// A run config fragment with the tuned gains: `servo run -c FILE` runs them.
    pub fn to_toml(&self) -> String {
        let p = &self.pid;
        format!(
            "# PID tuned by `servo tune` for |S| <= {}, |T| <= {}, |T| >= -3 dB at {} Hz:\n\
             # max|S| {:.3}, closed-loop bandwidth {:.0} Hz, predicted RMS following {:.3} nm / true {:.3} nm.\n\
             [controller.pid]\nkp = {:e}\nki = {:e}\nkd = {:e}\ntf_s = {:e}\n",
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
            p.tf_s
        )
    }
}

fn with_gains(cfg: &Loaded, k: [f64; 3]) -> Loaded {
    let mut c = cfg.clone();
    c.config.controller.pid.kp = k[0];
    c.config.controller.pid.ki = k[1];
    c.config.controller.pid.kd = k[2];
    c
}

/// The sampled plant: DAC command (V) → gap reading (V), at `freq_hz`.
fn plant_response(cfg: &Loaded, freq_hz: &[f64]) -> Result<Vec<Complex64>, RunError> {
    let c = &cfg.config;
    let sim = Simulator::new(&c.plant, 0, &Default::default()).map_err(|e| plant_error(e, cfg))?;
    let s = c.plant.capa.sensitivity_v_per_m;
    let open = ClosedLoop::open(&sim, s)
        .ok_or_else(|| RunError::Plant("tuning needs the ideal current-loop model".into()))?;
    Ok(freq_hz
        .iter()
        .map(|&f| open.command_response(f).unwrap_or_default() * s)
        .collect())
}

/// The discrete PID's response per unit gain (`kp`, `ki`, `kd`), the run's `tf_s` and period.
fn pid_basis(cfg: &Loaded, freq_hz: &[f64]) -> Result<Vec<[Complex64; 3]>, RunError> {
    let c = &cfg.config;
    let period = c.plant.period_s();
    let unit = |j: usize| -> Result<StateSpace, RunError> {
        let mut g = [0.0; 3];
        g[j] = 1.0;
        let pid = PidConfig {
            kp: g[0],
            ki: g[1],
            kd: g[2],
            tf_s: c.controller.pid.tf_s,
            limits: servo_core::Limits::UNLIMITED,
        }
        .try_build(period)
        .map_err(|e| cfg.invalid("controller.pid.tf_s", e, "> 0 s"))?;
        let (a, b, cc, d) = pid.coeffs().realization();
        Ok(StateSpace {
            a: dm(&a),
            b: dm(&b),
            c: dm(&cc),
            d: DMatrix::from_element(1, 1, d),
        })
    };
    let units = [unit(0)?, unit(1)?, unit(2)?];
    Ok(freq_hz
        .iter()
        .map(|&f| {
            let r = |j: usize| {
                units[j]
                    .freq_response_discrete(f, period)
                    .map(|m| m[(0, 0)])
                    .unwrap_or_default()
            };
            [r(0), r(1), r(2)]
        })
        .collect())
}

/// Evaluates gains `k` on the sampled loop of `cfg`.
fn report(cfg: &Loaded, k: [f64; 3], fine: &PidTuning) -> Result<PidReport, RunError> {
    let with = with_gains(cfg, k);
    let (cl, _) = closed_loop(&with)?;
    let budget = Budget::new(&cl, 400).map_err(|e| RunError::Plant(e.to_string()))?;
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

/// Tunes the PID of `cfg`: largest `ki` with `|S| ≤ ms`, `|T| ≤ mt` and `|T| ≥ −3 dB` at
/// `bandwidth_hz`.
pub fn tune(cfg: &Loaded, bandwidth_hz: f64, ms: f64, mt: f64) -> Result<TuneReport, RunError> {
    cfg.config.validate(cfg)?;
    for (key, v) in [("--ms", ms), ("--mt", mt)] {
        if !(v > 1.0 && v < 10.0) {
            return Err(cfg.invalid(key, v, "1 < M < 10").into());
        }
    }
    let fs = cfg.config.plant.timing.servo_rate_hz;
    if !(bandwidth_hz > 0.0 && bandwidth_hz < 0.25 * fs) {
        return Err(cfg
            .invalid("--bandwidth-hz", bandwidth_hz, "0 < f < servo rate / 4")
            .into());
    }
    let problem = |points: usize| -> Result<PidTuning, RunError> {
        let freq_hz = design::spectral::log_space(1.0, 0.499 * fs, points);
        let p = &cfg.config.controller.pid;
        Ok(PidTuning {
            plant: plant_response(cfg, &freq_hz)?,
            basis: pid_basis(cfg, &freq_hz)?,
            freq_hz,
            ms,
            mt,
            bandwidth_hz,
            upper: [20.0 * p.kp, 20.0 * p.ki, 20.0 * p.kd],
        })
    };
    let coarse = problem(600)?;
    let fine = problem(4000)?;
    let p = &cfg.config.controller.pid;
    let thesis = [p.kp, p.ki, p.kd];
    // Start: the configured PID scaled down until it is stable and inside the Ms bound.
    let start = (0..60)
        .map(|i| 0.85f64.powi(i))
        .map(|a| thesis.map(|g| g * a))
        .find(|k| {
            let (s, t, _) = coarse.evaluate(k);
            s <= ms
                && t <= mt
                && closed_loop(&with_gains(cfg, *k))
                    .map(|(cl, _)| cl.spectral_radius() < 1.0)
                    .unwrap_or(false)
        })
        .ok_or_else(|| {
            RunError::Plant(format!(
                "no scaling of the configured PID is stable with |S| ≤ {ms}, |T| ≤ {mt}: raise --ms or --mt"
            ))
        })?;
    let PidTuned {
        gains, iterations, ..
    } = coarse.solve(start, 200)?;
    let tuned = report(cfg, gains, &fine)?;
    let reference = report(cfg, thesis, &fine)?;
    Ok(TuneReport {
        ms,
        mt,
        bandwidth_target_hz: bandwidth_hz,
        iterations,
        tuned,
        reference,
        pid: PidGains {
            kp: gains[0],
            ki: gains[1],
            kd: gains[2],
            tf_s: cfg.config.controller.pid.tf_s,
        },
    })
}
