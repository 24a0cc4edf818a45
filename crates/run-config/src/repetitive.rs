//! Repetitive control of a machining run as configured (`[scenario.repetitive]`): the learning
//! law of `servo_core::Repetitive`, when it is switched on and off, and a table to start from.
//! Range checks only; the convergence check on the run's loop is `crate::repetitive`'s.

use super::{ConfigError, Origin};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Bins the runner's repetitive controller can hold (`servo_core::Repetitive<8192>`, 64 KiB).
pub const MAX_BINS: usize = 8192;

/// `[scenario.repetitive]`: a correction added to the surface reference, learned per
/// revolution from the measured error and indexed by the tracked spindle angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RepetitiveSection {
    /// Bins per revolution, [68, 8192] and at most half the ticks of one revolution at the
    /// fastest speed (4096).
    pub bins_per_rev: usize,
    /// Learning gain `k_r`, [1e-6, 2 − 1e-6]: the fraction of a revolution's error learned per
    /// revolution (0.5).
    pub learning_gain: f64,
    /// Robustness filter weight `q₁` on each neighbouring bin, [0, 0.25] (0.25: the binomial
    /// `[¼, ½, ¼]`).
    pub q_neighbour: f64,
    /// Lead in ticks, [0, 1000]; absent: the lead that makes the slowest harmonic converge
    /// fastest on the run's sampled loop.
    pub lead_ticks: Option<f64>,
    /// Taps of the learning filter on each side, [0, 8] bins: an FIR over neighbouring bins
    /// fitted to the inverse of the run's sampled loop (with the lead); 0: the lead alone.
    pub learning_filter_half_taps: usize,
    /// Largest correction in m, [1e-12, 1e-3] (10e-6).
    pub limit_m: f64,
    /// When the correction is switched on, s from the start (0); it ramps in over a revolution.
    pub on_at_s: f64,
    /// When it is switched off, s from the start (absent: never); it ramps out over a
    /// revolution and the table is kept.
    pub off_at_s: Option<f64>,
    /// A learned table to start from (`repetitive_table.csv` of an earlier run: `angle_rad,
    /// correction_m`, one row per bin), relative to the config file.
    pub table: Option<PathBuf>,
}

impl Default for RepetitiveSection {
    fn default() -> Self {
        RepetitiveSection {
            bins_per_rev: 4096,
            learning_gain: 0.5,
            q_neighbour: 0.25,
            lead_ticks: None,
            learning_filter_half_taps: 0,
            limit_m: 10e-6,
            on_at_s: 0.0,
            off_at_s: None,
            table: None,
        }
    }
}

impl RepetitiveSection {
    /// Checks the values' ranges (the bins against the speed and the convergence are checked
    /// when the run is planned).
    pub fn validate(&self, at: &Origin) -> Result<(), ConfigError> {
        let check = |key: &str, v: f64, ok: bool, range: &str| {
            if ok && v.is_finite() {
                Ok(())
            } else {
                Err(at.invalid(&format!("scenario.repetitive.{key}"), v, range))
            }
        };
        let n = self.bins_per_rev;
        check(
            "bins_per_rev",
            n as f64,
            (servo_core::MIN_BINS..=MAX_BINS).contains(&n),
            "[68, 8192] bins",
        )?;
        let g = self.learning_gain;
        check(
            "learning_gain",
            g,
            (1e-6..=2.0 - 1e-6).contains(&g),
            "[1e-6, 2 − 1e-6]",
        )?;
        let q = self.q_neighbour;
        check("q_neighbour", q, (0.0..=0.25).contains(&q), "[0, 0.25]")?;
        if let Some(m) = self.lead_ticks {
            check(
                "lead_ticks",
                m,
                (0.0..=1000.0).contains(&m),
                "[0, 1000] ticks",
            )?;
        }
        let h = self.learning_filter_half_taps;
        check(
            "learning_filter_half_taps",
            h as f64,
            h <= servo_core::LEARNING_TAPS / 2,
            "[0, 8] bins",
        )?;
        let l = self.limit_m;
        check("limit_m", l, (1e-12..=1e-3).contains(&l), "[1e-12, 1e-3] m")?;
        let on = self.on_at_s;
        check("on_at_s", on, (0.0..=1e6).contains(&on), "[0, 1e6] s")?;
        if let Some(off) = self.off_at_s {
            check("off_at_s", off, off > on && off <= 1e6, "(on_at_s, 1e6] s")?;
        }
        Ok(())
    }
}
