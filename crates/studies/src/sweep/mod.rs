//! The bandwidth sweep of thesis Fig 5-14: the PID brought to each bandwidth — its gains
//! scaled together, or re-tuned at each point as §5.7.3 did ("the controller gains were
//! adjusted from low to high, resulting in various cross over frequencies") by the
//! loop-shaping rule §5.6 cites ([`loop_shaped`]) — the predicted RMS following and true errors
//! from the budget, optionally checked against time-domain runs, and the optimum marked.
//! Bandwidths no stable PID reaches are kept with the reason.

mod loop_shape;

use crate::budget::Budget;
use crate::error::StudyError;
use plant_sim::params::StageParams;
use run_config::PidGains;
use runner::run::run_to_end;
use runner::Plan;
use serde::Serialize;

/// One bandwidth of the sweep.
#[derive(Debug, Clone, Serialize)]
pub struct SweepPoint {
    /// Requested bandwidth in Hz: the −3 dB bandwidth when scaled, the loop-gain crossover
    /// when re-tuned.
    pub target_hz: f64,
    /// Achieved −3 dB bandwidth in Hz.
    pub bandwidth_hz: f64,
    /// The PID at this point.
    pub pid: PidGains,
    /// Its gains over the configured PID's (the `kp` ratio when re-tuned; NaN for a
    /// configured `kp` of 0).
    pub gain_scale: f64,
    /// Predicted RMS following error in m.
    pub predicted_following_m: f64,
    /// Predicted RMS true error in m.
    pub predicted_true_m: f64,
    /// Simulated RMS following error in m (when validated).
    pub simulated_following_m: Option<f64>,
    /// Simulated RMS true error in m.
    pub simulated_true_m: Option<f64>,
}

/// A sweep for one configuration.
#[derive(Debug, Clone, Serialize)]
pub struct Sweep {
    /// Label (e.g. the mass).
    pub label: String,
    /// How the PID was brought to each bandwidth.
    pub tuning: SweepTuning,
    /// Points in bandwidth order.
    pub points: Vec<SweepPoint>,
    /// Requested bandwidths no PID reached, Hz, with the reason.
    pub unreached: Vec<(f64, String)>,
    /// The smallest predicted following error and the band around it.
    pub optimum_following: Optimum,
    /// The smallest predicted true error and the band around it.
    pub optimum_true: Optimum,
}

/// How close to the lowest error a bandwidth must come to count as optimal too: 0.5 %.
pub const FLATNESS: f64 = 0.005;

/// The lowest predicted error of a sweep and how flat the curve is around it (the error
/// curves of Fig 5-14 are shallow: a single bandwidth would claim more than they say).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Optimum {
    /// Bandwidth of the sweep's lowest point, Hz (NaN for an empty sweep).
    pub bandwidth_hz: f64,
    /// Its RMS error, m.
    pub rms_m: f64,
    /// The bandwidths between which the error stays within [`FLATNESS`] of the lowest, Hz
    /// (interpolated, log frequency against error, between sweep points).
    pub flat_hz: [f64; 2],
    /// Whether the flat band reaches the sweep's lowest or highest bandwidth (it may extend
    /// beyond).
    pub flat_to_end: [bool; 2],
}

impl Optimum {
    /// The optimum of `(bandwidth Hz, error m)` points in bandwidth order.
    pub fn of(points: &[(f64, f64)]) -> Optimum {
        let Some(best) = (0..points.len()).min_by(|&a, &b| points[a].1.total_cmp(&points[b].1))
        else {
            return Optimum {
                bandwidth_hz: f64::NAN,
                rms_m: f64::NAN,
                flat_hz: [f64::NAN; 2],
                flat_to_end: [false; 2],
            };
        };
        let (f0, e0) = points[best];
        let limit = e0 * (1.0 + FLATNESS);
        // Where the error passes the limit between neighbours i (inside) and j (outside).
        let edge = |i: usize, j: usize| {
            let ((fi, ei), (fj, ej)) = (points[i], points[j]);
            let t = (limit - ei) / (ej - ei);
            libm::exp(libm::log(fi) + t * (libm::log(fj) - libm::log(fi)))
        };
        let below = (0..best).rev().find(|&j| points[j].1 > limit);
        let above = (best + 1..points.len()).find(|&j| points[j].1 > limit);
        Optimum {
            bandwidth_hz: f0,
            rms_m: e0,
            flat_hz: [
                below.map_or(points[0].0, |j| edge(j + 1, j)),
                above.map_or(points[points.len() - 1].0, |j| edge(j - 1, j)),
            ],
            flat_to_end: [below.is_none(), above.is_none()],
        }
    }

    /// "560 Hz (0.831 nm; within 0.5 % from 470 to 690 Hz)".
    pub fn describe(&self) -> String {
        let end = |hz: f64, open: bool, word: &str| {
            if open {
                format!("{word} {hz:.0} Hz (the sweep's end)")
            } else {
                format!("{word} {hz:.0} Hz")
            }
        };
        format!(
            "{:.0} Hz ({:.3} nm; within {} % {} {})",
            self.bandwidth_hz,
            self.rms_m * 1e9,
            FLATNESS * 100.0,
            end(self.flat_hz[0], self.flat_to_end[0], "from"),
            end(self.flat_hz[1], self.flat_to_end[1], "to")
        )
    }
}

pub use loop_shape::loop_shaped;

/// How the sweep brings the PID to each bandwidth.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepTuning {
    /// All gains of the configured PID scaled by one factor (its shape kept) to reach each
    /// −3 dB bandwidth.
    Scaled,
    /// Re-tuned at each loop-gain crossover frequency by the rule [`loop_shaped`].
    Retuned,
}

/// The bandwidths of Fig 5-14's sweep, Hz (with the thesis's optima 468 and 874 Hz).
pub const THESIS_BANDWIDTHS_HZ: [f64; 10] = [
    200.0, 300.0, 400.0, 468.0, 600.0, 750.0, 874.0, 1000.0, 1200.0, 1450.0,
];

/// The two stages of Fig 5-14 and their labels.
pub const THESIS_STAGES: [(&str, StageParams); 2] = [
    ("0.074 kg", StageParams::THESIS),
    ("0.174 kg", StageParams::THESIS_HEAVY),
];

/// `plan` with the PID `pid`.
fn with_pid(plan: &Plan, pid: PidGains) -> Result<Plan, StudyError> {
    let mut c = plan.config.controller.clone();
    c.pid = pid;
    Ok(plan.with_controller(c)?)
}

/// The configured PID with its gains scaled by `k`.
fn scaled_pid(plan: &Plan, k: f64) -> PidGains {
    let p = plan.config.controller.pid;
    PidGains {
        kp: p.kp * k,
        ki: p.ki * k,
        kd: p.kd * k,
        ..p
    }
}

/// `plan` with its PID gains scaled by `k`.
pub fn scaled(plan: &Plan, k: f64) -> Result<Plan, StudyError> {
    with_pid(plan, scaled_pid(plan, k))
}

/// The PID reaching `target_hz` the way `tuning` says, with its bandwidth (Hz) and its scale
/// over the configured PID; Err(reason) when none does.
fn pid_for(
    plan: &Plan,
    target_hz: f64,
    tuning: SweepTuning,
) -> Result<Result<(PidGains, f64, f64), String>, StudyError> {
    match tuning {
        SweepTuning::Scaled => Ok(scale_for_bandwidth(plan, target_hz)?
            .map(|(k, bw)| (scaled_pid(plan, k), bw, k))
            .ok_or_else(|| {
                "no stable scaling of the PID has its first −3 dB crossing there: none reaches it, or the crossing jumps past it as the gain lifts a dip of |T| (the m4 mode)".to_owned()
            })),
        SweepTuning::Retuned => {
            let pid = loop_shaped(plan, target_hz)?;
            let cl = with_pid(plan, pid)?.closed_loop;
            let radius = cl.spectral_radius();
            let kp = plan.config.controller.pid.kp;
            let scale = if kp != 0.0 { pid.kp / kp } else { f64::NAN };
            Ok(if radius < 1.0 {
                Ok((pid, cl.bandwidth_hz()?, scale))
            } else {
                Err(format!(
                    "the loop-shaped PID is unstable on the sampled loop (spectral radius {radius:.4})"
                ))
            })
        }
    }
}

/// The gain scale giving bandwidth `target_hz` (the first −3 dB crossing,
/// [`loop_model::closed_loop::ClosedLoop::bandwidth_hz`]): a log scan from 1/100 to 100 finds the
/// first pair of neighbouring *stable* gains that bracket the target (very low gains can be
/// unstable too, so plain bisection would be misled), then bisection refines it. `None` when no
/// stable gain gives it within 1 %: none reaches it, or the crossing jumps past it as the gain
/// rises (a dip of |T| below −3 dB that the gain lifts: the light stage's m4 mode near 422 Hz).
pub fn scale_for_bandwidth(plan: &Plan, target_hz: f64) -> Result<Option<(f64, f64)>, StudyError> {
    let bw = |k: f64| -> Result<Option<f64>, StudyError> {
        let cl = scaled(plan, k)?.closed_loop;
        Ok((cl.spectral_radius() < 1.0).then(|| cl.bandwidth_hz().unwrap_or(0.0)))
    };
    let grid: Vec<f64> = (0..=48)
        .map(|i| 0.01 * libm::pow(10f64, i as f64 / 12.0))
        .collect();
    let mut prev: Option<(f64, f64)> = None;
    for &k in &grid {
        let here = bw(k)?;
        if let (Some((k0, b0)), Some(b1)) = (prev, here) {
            if b0 < target_hz && b1 >= target_hz {
                let (mut lo, mut hi) = (k0, k);
                for _ in 0..30 {
                    let mid = (lo * hi).sqrt();
                    match bw(mid)? {
                        Some(b) if b < target_hz => lo = mid,
                        Some(_) => hi = mid,
                        None => break,
                    }
                }
                let k = (lo * hi).sqrt();
                return Ok(bw(k)?
                    .filter(|b| (b / target_hz - 1.0).abs() < 0.01)
                    .map(|b| (k, b)));
            }
        }
        prev = here.map(|b| (k, b));
    }
    Ok(None)
}

/// Runs the sweep over `targets_hz`, the PID brought to each by `tuning`; with `simulate_s`,
/// each point is also simulated for that long (seeded as in `plan`). `progress` gets (done,
/// total) points.
pub fn sweep(
    plan: &Plan,
    label: &str,
    targets_hz: &[f64],
    tuning: SweepTuning,
    simulate_s: Option<f64>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Sweep, StudyError> {
    let mut points = Vec::new();
    let mut unreached = Vec::new();
    for (i, &target) in targets_hz.iter().enumerate() {
        progress(i, targets_hz.len());
        let (pid, bw, gain_scale) = match pid_for(plan, target, tuning)? {
            Ok(found) => found,
            Err(reason) => {
                unreached.push((target, reason));
                continue;
            }
        };
        let at = with_pid(plan, pid)?;
        let budget = Budget::new(&at.closed_loop, 64)?;
        let (mut sf, mut st) = (None, None);
        if let Some(d) = simulate_s {
            let s = run_to_end(&at.with_duration(d)?)?;
            (sf, st) = (Some(s.following_error_m.rms), Some(s.true_error_m.rms));
        }
        points.push(SweepPoint {
            target_hz: target,
            bandwidth_hz: bw,
            pid,
            gain_scale,
            predicted_following_m: budget.following_rms_m,
            predicted_true_m: budget.true_rms_m,
            simulated_following_m: sf,
            simulated_true_m: st,
        });
    }
    progress(targets_hz.len(), targets_hz.len());
    // Re-tuned loops need not reach bandwidths in the order of their crossovers.
    points.sort_by(|a, b| a.bandwidth_hz.total_cmp(&b.bandwidth_hz));
    let best = |f: fn(&SweepPoint) -> f64| {
        Optimum::of(
            &points
                .iter()
                .map(|p| (p.bandwidth_hz, f(p)))
                .collect::<Vec<_>>(),
        )
    };
    Ok(Sweep {
        label: label.to_owned(),
        tuning,
        unreached,
        optimum_following: best(|p| p.predicted_following_m),
        optimum_true: best(|p| p.predicted_true_m),
        points,
    })
}

/// Fig 5-14: the sweep of `plan`'s controller over `targets_hz` for both thesis stages
/// ([`THESIS_STAGES`]); `progress` gets (done, total) points over both.
pub fn thesis_sweeps(
    plan: &Plan,
    targets_hz: &[f64],
    tuning: SweepTuning,
    simulate_s: Option<f64>,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<Vec<Sweep>, StudyError> {
    let total = THESIS_STAGES.len() * targets_hz.len();
    THESIS_STAGES
        .iter()
        .enumerate()
        .map(|(i, (label, stage))| {
            let mut loaded = run_config::Loaded {
                config: plan.config.clone(),
                origin: plan.origin.clone(),
            };
            loaded.config.plant.stage = *stage;
            let offset = i * targets_hz.len();
            sweep(
                &Plan::new(&loaded)?,
                label,
                targets_hz,
                tuning,
                simulate_s,
                &mut |done, _| progress(offset + done, total),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On e(f) = 1 + (ln f/500)², the band within 0.5 % of the minimum is
    /// 500·e^{±√0.005} = 482.6 … 518.0 Hz; points every 2 % find it to interpolation accuracy,
    /// and a curve still inside the band at the last point says the band runs to the end.
    #[test]
    fn the_flat_band_is_where_the_error_stays_within_half_a_percent() {
        let e = |f: f64| 1.0 + libm::log(f / 500.0).powi(2);
        let points: Vec<(f64, f64)> = (0..60)
            .map(|i| 300.0 * 1.02f64.powi(i))
            .map(|f| (f, e(f)))
            .collect();
        let o = Optimum::of(&points);
        let half_width = FLATNESS.sqrt();
        let want = [
            500.0 * libm::exp(-half_width),
            500.0 * libm::exp(half_width),
        ];
        for (got, want) in o.flat_hz.iter().zip(want) {
            assert!((got / want - 1.0).abs() < 2e-3, "{got} vs {want}");
        }
        assert_eq!(o.flat_to_end, [false, false]);
        assert!((o.bandwidth_hz / 500.0 - 1.0).abs() < 0.01);
        let cut = Optimum::of(&points[..27]);
        assert_eq!(cut.flat_to_end, [false, true]);
    }
}
