//! Repetitive control of a machining run, planned on its sampled loop: the convergence check
//! (refused when learning would diverge at some harmonic), the lead when none is configured,
//! the target the measured error is taken against, and the learned table as a file.
//!
//! The controller learns from what it measures: the gap sensor on the coil carrier, which
//! lags the tool by its filter and the sampling (≈ 4.3 ticks on the default stage). Learned
//! against the design surface itself, the correction would make the *sensor* follow it and
//! cut the lag into the part (ZPETC's `zpetc-sensor` case). So unless the feedforward targets
//! the sensor, the error is taken against the surface `lag_ticks` earlier — the model's delay
//! from the tool to the reading at low frequency — and the tool converges to the surface.

use crate::error::RunError;
use design::repetitive::{Convergence, Harmonics, Learning};
use loop_model::closed_loop::{input, output, reference_path_response, ClosedLoop};
use loop_model::measured_loop::{Extended, MeasuredLoop};
use recorder::Input;
use run_config::Origin;
use run_config::{FeedforwardKind, Machining, RepetitiveSection, RunConfig, MAX_BINS};
use servo_config::Deployment;
use servo_core::{RepetitiveConfig, LEARNING_IDENTITY, LEARNING_TAPS};
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::Path;

/// Name of a starting table among a run's inputs (and in its recording).
pub const TABLE_INPUT: &str = "repetitive_table.csv";

/// Name of the table a run learned, in its recording (attached at the end).
pub const LEARNED_ATTACHMENT: &str = "repetitive_learned.csv";

/// Largest table file read, bytes (8192 rows of two numbers).
const MAX_TABLE_BYTES: u64 = 1 << 20;

/// Frequency at which the sensor's lag behind the tool is measured, Hz.
const LAG_PROBE_HZ: f64 = 100.0;

/// Longest lead searched, ticks.
const MAX_AUTO_LEAD_TICKS: f64 = 200.0;

/// A machining run's repetitive controller, checked on its loop.
#[derive(Debug, Clone, PartialEq)]
pub struct RepetitivePlan {
    /// The block's configuration (the lead chosen when none was configured).
    pub config: RepetitiveConfig,
    /// The slowest harmonic's convergence per revolution on the run's loop.
    pub convergence: Convergence,
    /// The error compares the measured position with the surface this many ticks earlier
    /// (the tool → reading delay less the tick the reference leads; −1 for a sensor target).
    pub lag_ticks: f64,
    /// Switched on at this tick.
    pub on_tick: u64,
    /// Switched off at this tick, if ever.
    pub off_tick: Option<u64>,
    /// The table it starts from, m per bin.
    pub table: Option<Vec<f64>>,
    /// Gap reading per metre, V/m.
    pub sensitivity_v_per_m: f64,
    /// What the convergence was checked on: the model's loop, or the loop closed on a measured
    /// FRF (and what it assumed beyond the measured band).
    pub checked_on: String,
}

/// Plans `s` for the machining `m` of `config` on the loop `cl` running `deployment` — or, when
/// the run names a measured FRF, on the loop closed on it (`measured`), each harmonic judged
/// over its uncertainty disk; a starting table is taken from `inputs` ([`TABLE_INPUT`]) or
/// read and added there.
#[allow(clippy::too_many_arguments)]
pub fn plan(
    config: &RunConfig,
    m: &Machining,
    s: &RepetitiveSection,
    cl: &ClosedLoop,
    measured: Option<&MeasuredLoop>,
    deployment: &Deployment,
    origin: &Origin,
    inputs: &mut Vec<Input>,
) -> Result<RepetitivePlan, RunError> {
    let period = cl.period_s;
    let nominal = m.spindle_rpm / 60.0;
    let slow = 1.0 - m.spindle_drift_fraction + m.spindle_step_fraction.min(0.0);
    let fast = 1.0 + m.spindle_drift_fraction + m.spindle_step_fraction.max(0.0);
    let block = |lead_ticks: f64, learning_filter: [f64; LEARNING_TAPS]| RepetitiveConfig {
        bins_per_rev: s.bins_per_rev,
        learning_gain: s.learning_gain,
        lead_ticks,
        learning_filter,
        q_neighbour: s.q_neighbour,
        limit_m: s.limit_m,
        max_speed_rpm: m.spindle_rpm * fast,
    };
    // The bins against the fastest speed, before the loop is evaluated at each harmonic.
    block(0.0, LEARNING_IDENTITY)
        .try_build::<MAX_BINS>(period)
        .map_err(|e| refused(origin, e))?;
    // Slowest to fastest: equal neighbours (no drift, no step) are evaluated once.
    let mut speeds = vec![nominal * slow, nominal, nominal * fast];
    speeds.dedup();
    let response = reference_path_response(cl, deployment, output::MEASURED_M);
    let (harmonics, checked_on) = match measured {
        None => (
            Harmonics::sample(s.bins_per_rev, &speeds, period, &response),
            "the model's loop".to_owned(),
        ),
        Some(measured) => {
            let extended = measured_path(measured, deployment, &response);
            (
                Harmonics::sample_within(s.bins_per_rev, &speeds, period, |f| {
                    extended.at(f, response(f))
                }),
                format!(
                    "the loop closed on the measured FRF {} up to {:.0} Hz, over each bin's uncertainty; beyond it the model's loop within ±{:.1} %",
                    measured.source,
                    extended.top_hz,
                    100.0 * extended.beyond
                ),
            )
        }
    };
    let mut learning = Learning {
        bins_per_rev: s.bins_per_rev,
        learning_gain: s.learning_gain,
        q_neighbour: s.q_neighbour,
        filter: vec![1.0],
    };
    let mut convergence = match s.lead_ticks {
        Some(lead) => harmonics.convergence(&learning, lead),
        None => harmonics.best_lead(&learning, MAX_AUTO_LEAD_TICKS),
    };
    let half = s.learning_filter_half_taps;
    let mut taps = LEARNING_IDENTITY;
    if half > 0 {
        let lead = convergence.lead_ticks;
        learning.filter = harmonics.fit_filter(&learning, lead, half);
        let centre = LEARNING_TAPS / 2;
        taps = [0.0; LEARNING_TAPS];
        taps[centre - half..=centre + half].copy_from_slice(&learning.filter);
        convergence = harmonics.convergence(&learning, lead);
    }
    if convergence.factor.is_nan() || convergence.factor >= 1.0 {
        return Err(origin
            .invalid(
                "scenario.repetitive.learning_gain",
                s.learning_gain,
                &format!(
                    "a learning law that converges on this loop: at harmonic {} ({:.0} Hz) a revolution multiplies the error by {:.3} with lead {:.2} ticks (must be < 1; checked on {checked_on}); lower learning_gain, raise q_neighbour toward 0.25, or leave lead_ticks out to have it chosen",
                    convergence.harmonic, convergence.frequency_hz, convergence.factor, convergence.lead_ticks
                ),
            )
            .into());
    }
    let lag_ticks = match config.controller.feedforward {
        FeedforwardKind::ZpetcSensor => -1.0,
        _ => {
            sensor_delay_ticks(cl).ok_or_else(|| {
                origin.invalid(
                    "scenario.repetitive",
                    "(the loop's sensor delay)",
                    "a loop whose reading and tool responses can be evaluated at 100 Hz",
                )
            })? - 1.0
        }
    };
    // The block is built from the final law: its lead plus the reference's preview must stay
    // short of the bins learned this revolution.
    let preview = (deployment.feedforward.preview() + deployment.smoothing_half()) as f64;
    block(convergence.lead_ticks + preview, taps)
        .try_build::<MAX_BINS>(period)
        .map_err(|e| refused(origin, e))?;
    let table = match &s.table {
        None => None,
        Some(path) => Some(load_table(path, s, inputs, origin)?),
    };
    let ticks = |t: f64| (t / period).round() as u64;
    Ok(RepetitivePlan {
        config: block(convergence.lead_ticks, taps),
        convergence,
        lag_ticks,
        on_tick: ticks(s.on_at_s),
        off_tick: s.off_at_s.map(ticks),
        table,
        sensitivity_v_per_m: config.plant.capa.sensitivity_v_per_m,
        checked_on,
    })
}

/// The reference path's response to the reading on the loop closed on `measured` (the run's
/// feedforward and smoothing applied, as `model` applies them on the model), extended beyond
/// the measured bins by the model.
fn measured_path(
    measured: &MeasuredLoop,
    deployment: &Deployment,
    model: &dyn Fn(f64) -> num_complex::Complex64,
) -> Extended {
    use num_complex::Complex64 as C;
    let at_bins: Vec<(C, f64)> = measured
        .freq_hz
        .iter()
        .enumerate()
        .map(|(k, &f)| {
            let p = servo_config::reference_path(deployment, f);
            let reference = C::new(p.reference[0], p.reference[1]);
            let command = C::new(p.feedforward_v_per_m[0], p.feedforward_v_per_m[1]);
            let (to_reading, sigma_r) = measured.reference_to_reading[k];
            let (from_command, sigma_c) = measured.command_to_reading[k];
            (
                to_reading * reference + from_command * command,
                sigma_r * reference.norm() + sigma_c * command.norm(),
            )
        })
        .collect();
    Extended::new(&measured.freq_hz, &at_bins, model)
}

/// The measured position's delay behind the tool at low frequency, ticks (the loop model's
/// tool at a tick's end against the sample the tick starts with).
fn sensor_delay_ticks(cl: &ClosedLoop) -> Option<f64> {
    let reading = cl.response(output::MEASURED_M, input::REFERENCE_M, LAG_PROBE_HZ);
    let tool = cl.response(output::TOOL_M, input::REFERENCE_M, LAG_PROBE_HZ);
    let ratio = reading.ok()? / tool.ok()?;
    ratio
        .is_finite()
        .then(|| -ratio.arg() / (TAU * LAG_PROBE_HZ * cl.period_s))
}

/// The block's refusal of the planned law, at the key that sets the refused value.
fn refused(origin: &Origin, e: servo_core::Error) -> RunError {
    let (param, value, range) = match e {
        servo_core::Error::OutOfRange {
            param,
            value,
            min,
            max,
        } => (param, value, format!("[{min}, {max}]")),
        servo_core::Error::NotFinite { param } => (param, f64::NAN, "a finite number".into()),
        other => ("bins_per_rev", f64::NAN, other.to_string()),
    };
    let (key, range) = match param {
        "learning_filter" => (
            "learning_filter_half_taps".to_owned(),
            format!("a filter whose fitted taps stay within {range} (fewer taps)"),
        ),
        "lead_ticks" => (
            param.to_owned(),
            format!("{range} ticks with the reference's preview added (short of the bins learned this revolution)"),
        ),
        "bins_per_rev" => (
            param.to_owned(),
            format!("{range}: at most half the ticks of one revolution at the fastest spindle speed"),
        ),
        _ => (param.to_owned(), range),
    };
    let key = if param == "max_speed_rpm" {
        "scenario.spindle_rpm".to_owned()
    } else {
        format!("scenario.repetitive.{key}")
    };
    origin.invalid(&key, value, &range).into()
}

/// The table of `s.table`: from `inputs` when there (a replay), else read and added.
fn load_table(
    path: &Path,
    s: &RepetitiveSection,
    inputs: &mut Vec<Input>,
    origin: &Origin,
) -> Result<Vec<f64>, RunError> {
    let key = "scenario.repetitive.table";
    let bytes = crate::run_input::input_or_read(inputs, TABLE_INPUT, "text/csv", || {
        daq_io::input_file::read_regular_text(path, MAX_TABLE_BYTES)
            .map(String::into_bytes)
            .map_err(|e| {
                origin.invalid(
                    key,
                    path.display(),
                    &format!("a UTF-8 CSV file, regular, of at most 1 MiB ({e})"),
                )
            })
    })?;
    let text = String::from_utf8_lossy(&bytes);
    parse_table(&text, s.bins_per_rev, s.limit_m).map_err(|why| {
        origin
            .invalid(
                key,
                path.display(),
                &format!("a table of this run's bins: {why}"),
            )
            .into()
    })
}

/// The correction column of a table written by [`table_csv`]: the header `angle_rad,
/// correction_m`, then `bins` rows of exactly those two columns, each at its bin's centre
/// angle (rad, to 1e-6) and within ±`limit_m`.
fn parse_table(text: &str, bins: usize, limit_m: f64) -> Result<Vec<f64>, String> {
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, h)) if h.trim() == "angle_rad,correction_m" => {}
        _ => return Err("line 1: the header `angle_rad,correction_m`".into()),
    }
    let mut out = Vec::with_capacity(bins);
    for (n, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        if out.len() == bins {
            return Err(format!("line {}: more than {bins} rows", n + 1));
        }
        let centre = TAU * (out.len() as f64 + 0.5) / bins as f64;
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let row = match fields[..] {
            [angle, value] => angle.parse::<f64>().ok().zip(value.parse::<f64>().ok()),
            _ => None,
        };
        let value = row
            .filter(|(angle, v)| (angle - centre).abs() <= 1e-6 && v.abs() <= limit_m)
            .map(|(_, v)| v)
            .ok_or_else(|| {
                format!(
                    "line {}: `angle_rad,correction_m`, two columns, the angle {centre:.9} rad (bin {} of {bins}) and |correction| ≤ {limit_m} m",
                    n + 1,
                    out.len()
                )
            })?;
        out.push(value);
    }
    if out.len() != bins {
        return Err(format!("{} rows, this run has {bins} bins", out.len()));
    }
    Ok(out)
}

/// What the recording's end record says of the repetitive controller.
pub fn end_facts(p: &RepetitivePlan, table: &[f64]) -> Vec<(String, String)> {
    let peak = table.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    vec![
        (
            "repetitive.law".into(),
            format!(
                "{} bins, learning gain {}, q1 {}, lead {:.2} ticks, learning filter {:?}, error against the surface {:.2} ticks earlier",
                p.config.bins_per_rev, p.config.learning_gain, p.config.q_neighbour, p.config.lead_ticks, fitted_taps(&p.config.learning_filter), p.lag_ticks
            ),
        ),
        (
            "repetitive.convergence".into(),
            format!(
                "slowest harmonic {} ({:.0} Hz): error × {:.3} per revolution",
                p.convergence.harmonic, p.convergence.frequency_hz, p.convergence.factor
            ),
        ),
        (
            "repetitive.table".into(),
            format!("{LEARNED_ATTACHMENT}: largest correction {:.1} nm", peak * 1e9),
        ),
    ]
}

/// The learning filter's taps from the first to the last nonzero one.
pub fn fitted_taps(filter: &[f64; LEARNING_TAPS]) -> &[f64] {
    let first = filter.iter().position(|t| *t != 0.0).unwrap_or(0);
    let last = filter.iter().rposition(|t| *t != 0.0).unwrap_or(0);
    &filter[first..=last.max(first)]
}

/// A learned table as CSV: `angle_rad,correction_m`, one row per bin (its centre).
pub fn table_csv(table: &[f64]) -> String {
    let mut s = String::from("angle_rad,correction_m\n");
    let n = table.len() as f64;
    for (i, v) in table.iter().enumerate() {
        let _ = writeln!(s, "{:.9},{v:e}", TAU * (i as f64 + 0.5) / n);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_written_table_reads_back() {
        let table: Vec<f64> = (0..64).map(|i| 1e-9 * f64::from(i) - 3e-8).collect();
        let text = table_csv(&table);
        assert_eq!(parse_table(&text, 64, 1e-6).unwrap(), table);
        // Too few rows (the angles of 64 bins are not those of 65).
        let mut short = text.clone();
        short.truncate(text.trim_end().rfind('\n').unwrap() + 1);
        assert!(parse_table(&short, 64, 1e-6)
            .unwrap_err()
            .contains("63 rows"));
        assert!(parse_table(&text, 64, 1e-8).unwrap_err().contains("line 2"));
        // An extra column, a table of another bin count, a missing header: refused, located.
        let extra: String = text
            .lines()
            .enumerate()
            .map(|(i, l)| {
                if i == 1 {
                    format!("{l},0\n")
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        assert!(parse_table(&extra, 64, 1e-6)
            .unwrap_err()
            .contains("line 2: `angle_rad,correction_m`, two columns"));
        let other = table_csv(&table[..32]);
        assert!(parse_table(&other, 32, 1e-6).is_ok());
        assert!(parse_table(&other, 64, 1e-6)
            .unwrap_err()
            .contains("line 2"));
        assert!(parse_table(&text[23..], 64, 1e-6)
            .unwrap_err()
            .contains("line 1: the header"));
    }
}
