//! One point of a study: its plant, its controller (the family's design), and what the loop
//! does — stability, margins, bandwidth and the exact error budget. Each point is what
//! `servo synth h2` (or `servo tune`) followed by `servo budget` gives for the same plant.

use super::sampling;
use super::spec::{Family, Study, MOVING_MASS_KEY};
use crate::budget::Budget;
use crate::error::StudyError;
use crate::margins::loop_margins;
use crate::synth::h2_design_with;
use loop_model::closed_loop::SOURCES;
use run_config::{ControllerConfig, ControllerKind, Loaded, RunConfig};
use runner::Plan;
use serde::Serialize;
use std::path::PathBuf;

/// What the loop of one successful point does.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// Closed-loop −3 dB bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// RMS following error, m.
    pub following_rms_m: f64,
    /// RMS true error, m.
    pub true_rms_m: f64,
    /// Spectral radius of the sampled closed loop.
    pub spectral_radius: f64,
    /// Phase margin at the actuator, degrees (NaN: no gain crossover).
    pub phase_margin_deg: f64,
    /// Gain margin at the actuator, dB (NaN: no phase crossover below unity gain).
    pub gain_margin_db: f64,
    /// States of the controller.
    pub controller_states: usize,
    /// The design's own knob: ρ (nm/V) for `h2`, the sensor-noise scale of the design for
    /// `h2-bandwidth`, NaN for `pid`.
    pub design_value: f64,
    /// PID gains kp (V/V), ki (V/V/s), kd (V·s/V) for `pid`; NaN otherwise.
    pub pid: [f64; 3],
    /// RMS following error per source ([`SOURCES`] order), m.
    pub following_by_source_m: Vec<f64>,
    /// RMS true error per source, m.
    pub true_by_source_m: Vec<f64>,
}

/// One point's result: the metrics, or why the point failed (never dropped).
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Index in the study (`family × points per family + sample`).
    pub index: u64,
    /// Controller family.
    pub family: Family,
    /// Parameter values, in the study's parameter order and units.
    pub values: Vec<f64>,
    /// The loop's metrics, or the reason the point failed.
    pub outcome: Result<Metrics, String>,
}

/// Number of error sources each point reports.
pub const SOURCE_COUNT: usize = SOURCES.len();

/// The configuration of a point with `values` set over the operating point.
pub fn point_config(study: &Study, values: &[f64]) -> Result<RunConfig, String> {
    let mut tree = study.base.clone();
    for (p, &v) in study.table.parameters.iter().zip(values) {
        if p.key == MOVING_MASS_KEY {
            let stage = tree
                .get_mut("plant")
                .and_then(|t| t.get_mut("stage"))
                .ok_or("no [plant.stage]")?;
            let get = |t: &toml::Value, k: &str| t.get(k).and_then(toml::Value::as_float);
            let (m1, m2) = (get(stage, "m1_kg"), get(stage, "m2_kg"));
            let (Some(m1), Some(m2)) = (m1, m2) else {
                return Err("plant.stage.m1_kg and m2_kg must be numbers".into());
            };
            let k = v / (m1 + m2);
            stage["m1_kg"] = toml::Value::Float(m1 * k);
            stage["m2_kg"] = toml::Value::Float(m2 * k);
            continue;
        }
        let mut at = &mut tree;
        let parts: Vec<&str> = p.key.split('.').collect();
        for part in &parts[..parts.len() - 1] {
            at = at
                .get_mut(*part)
                .ok_or_else(|| format!("no table for {}", p.key))?;
        }
        let slot = at
            .get_mut(*parts.last().unwrap_or(&""))
            .ok_or_else(|| format!("no key {}", p.key))?;
        *slot = match slot {
            toml::Value::Integer(_) if v.fract() == 0.0 && v.abs() < 9.0e15 => {
                toml::Value::Integer(v as i64)
            }
            toml::Value::Integer(_) => {
                return Err(format!("{} = {v}: allowed whole numbers", p.key));
            }
            _ => toml::Value::Float(v),
        };
    }
    tree.try_into().map_err(|e: toml::de::Error| e.to_string())
}

/// Evaluates point `index` of `study`.
pub fn evaluate(study: &Study, index: u64) -> Point {
    let per_family = study.points_per_family();
    let family = study.table.controllers[(index / per_family) as usize];
    let values = sampling::values(study, index % per_family);
    let outcome = outcome(study, family, &values);
    Point {
        index,
        family,
        values,
        outcome,
    }
}

/// The loop of `family` at parameter `values` (the study's order), or why it failed — a panic
/// included, so that one point never stops a study.
pub fn outcome(study: &Study, family: Family, values: &[f64]) -> Result<Metrics, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        point_config(study, values)
            .and_then(|c| metrics(study, family, c).map_err(|e| e.to_string()))
    }))
    .unwrap_or_else(|_| Err("internal error (a panic) while evaluating the point".into()))
}

/// The loop of `config` under `family`'s controller, and its metrics.
pub fn metrics(study: &Study, family: Family, config: RunConfig) -> Result<Metrics, StudyError> {
    let plan = Plan::new(&Loaded {
        config,
        origin: study.origin.clone(),
    })?;
    let t = &study.table;
    let (plan, design_value, pid, states) = match family {
        Family::H2 => {
            let (p, n) = with_h2(&plan, t.effort_weight_nm_per_v, 1.0)?;
            (p, t.effort_weight_nm_per_v, [f64::NAN; 3], n)
        }
        Family::H2Bandwidth => {
            let (p, scale, n) = h2_at_bandwidth(&plan, t.effort_weight_nm_per_v, t.bandwidth_hz)?;
            (p, scale, [f64::NAN; 3], n)
        }
        Family::Pid => {
            let tuned = crate::tune::tune(&plan, t.bandwidth_hz, t.pid_ms, t.pid_mt)?.pid;
            let controller = ControllerConfig {
                kind: ControllerKind::Pid,
                pid: tuned,
                ..plan.config.controller.clone()
            };
            let p = plan.with_controller(controller)?;
            (p, f64::NAN, [tuned.kp, tuned.ki, tuned.kd], 3)
        }
    };
    let spectral_radius = plan.check_stable()?;
    let budget = Budget::new(&plan.closed_loop, 16)?;
    let margins = loop_margins(&plan)?;
    Ok(Metrics {
        bandwidth_hz: budget.bandwidth_hz,
        following_rms_m: budget.following_rms_m,
        true_rms_m: budget.true_rms_m,
        spectral_radius,
        phase_margin_deg: margins.phase_margin_deg.unwrap_or(f64::NAN),
        gain_margin_db: margins.gain_margin_db.unwrap_or(f64::NAN),
        controller_states: states,
        design_value,
        pid,
        following_by_source_m: budget
            .contributions
            .iter()
            .map(|c| c.following_rms_m)
            .collect(),
        true_by_source_m: budget.contributions.iter().map(|c| c.true_rms_m).collect(),
    })
}

/// `plan` closed by its H2 design (effort ρ, the design's sensor noise scaled by `scale`), loaded
/// from the controller file `servo synth h2` would write; with the controller's state count.
fn with_h2(plan: &Plan, effort: f64, scale: f64) -> Result<(Plan, usize), StudyError> {
    let design = h2_design_with(plan, effort, scale)?;
    let controller = ControllerConfig {
        kind: ControllerKind::Ss,
        ss_file: Some(PathBuf::from("h2.toml")),
        ..plan.config.controller.clone()
    };
    let states = design.controller.nx();
    let file = design.to_toml().into_bytes();
    Ok((plan.with_controller_file(controller, Some(file))?, states))
}

/// Relative bandwidth tolerance of the `h2-bandwidth` search.
const BANDWIDTH_TOLERANCE: f64 = 2e-3;
/// The search's sensor-noise scales span 10^±SCALE_DECADES.
const SCALE_DECADES: i32 = 6;

/// The H2 design whose closed loop has a −3 dB bandwidth of `target_hz` (within 0.2 %): the
/// design's assumed sensor noise scaled (smaller: the design trusts the sensor more and closes
/// a faster loop), found by stepping in decades until the bandwidth crosses the target, then
/// by regula falsi (Illinois) on log scale against log bandwidth. Returns the loop, the scale
/// and the controller's states.
fn h2_at_bandwidth(
    plan: &Plan,
    effort: f64,
    target_hz: f64,
) -> Result<(Plan, f64, usize), StudyError> {
    let unreachable = |reason: String| StudyError::BandwidthSearch {
        bandwidth_hz: target_hz,
        reason,
    };
    // The loop at 10^x times the sensor noise, and its miss ln(bandwidth / target).
    let at = |x: f64| -> Result<(Plan, usize, f64), StudyError> {
        let (p, n) = with_h2(plan, effort, libm::pow(10f64, x))?;
        let miss = libm::log(p.closed_loop.bandwidth_hz()? / target_hz);
        Ok((p, n, miss))
    };
    let (mut lo, first) = (0.0, at(0.0)?);
    if first.2.abs() <= BANDWIDTH_TOLERANCE {
        return Ok((first.0, 1.0, first.1));
    }
    let mut f_lo = first.2;
    // Too slow: trust the sensor more (smaller noise); too fast: less.
    let step = if f_lo < 0.0 { -1.0 } else { 1.0 };
    let mut bracket = None;
    for _ in 0..SCALE_DECADES {
        let x = lo + step;
        let (.., f) = at(x)?;
        if f.signum() != f_lo.signum() {
            bracket = Some((x, f));
            break;
        }
        (lo, f_lo) = (x, f);
    }
    let Some((mut hi, mut f_hi)) = bracket else {
        return Err(unreachable(format!(
            "{:.0} Hz with the design's sensor noise scaled by 10^{lo:+}",
            target_hz * libm::exp(f_lo)
        )));
    };
    // Regula falsi with the Illinois weights `w` (the true misses stay for the report).
    let (mut w_lo, mut w_hi) = (f_lo, f_hi);
    let mut last_side = 0;
    for _ in 0..60 {
        if (hi - lo).abs() < 1e-9 {
            break;
        }
        let x = hi - w_hi * (hi - lo) / (w_hi - w_lo);
        let (p, n, f) = at(x)?;
        if f.abs() <= BANDWIDTH_TOLERANCE {
            return Ok((p, libm::pow(10f64, x), n));
        }
        if f.signum() == f_hi.signum() {
            (hi, f_hi, w_hi) = (x, f, f);
            if last_side == 1 {
                w_lo /= 2.0;
            }
            last_side = 1;
        } else {
            (lo, f_lo, w_lo) = (x, f, f);
            if last_side == -1 {
                w_hi /= 2.0;
            }
            last_side = -1;
        }
    }
    Err(unreachable(format!(
        "the bandwidth jumps (within 60 steps of the search) from {:.0} to {:.0} Hz at a sensor-noise scale of {:.4e} (|T| crosses −3 dB at a shoulder of its curve)",
        target_hz * libm::exp(f_lo).min(libm::exp(f_hi)),
        target_hz * libm::exp(f_lo).max(libm::exp(f_hi)),
        libm::pow(10f64, lo)
    )))
}
