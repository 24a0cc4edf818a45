//! The intermittent-cut experiment of thesis §7.6 for a list of acceleration gains: a face
//! cut over a part milled half lower, so the cutting force steps on and off twice per spindle
//! revolution; for each Ka the peak following error (Fig 7-17) and the height of the form
//! error the tool leaves at the step edge (Fig 7-19: the tool pushed away from the part
//! leaves material standing).

use crate::error::StudyError;
use run_config::{ControllerConfig, ControllerKind, Scenario};
use runner::run::run_to_end_with;
use runner::Plan;
use serde::Serialize;

/// Simulated seconds per Ka when the run length is not given (≈ 2 revolutions at 250 rpm).
pub const DEFAULT_DURATION_S: f64 = 0.5;

/// The acceleration gains of §7.5/§7.6, V/V.
pub const THESIS_KAS: [f64; 4] = [0.0, 0.5, 1.0, 4.0];

/// One acceleration gain's result.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct KaRow {
    /// Acceleration gain (V/V).
    pub ka: f64,
    /// PID gain factor applied (1/Kg with Kg scaling, else 1).
    pub pid_scale: f64,
    /// Largest |following error| (sensor) after settling, m (thesis: 75 → 25 nm, Ka 0 → 4).
    pub peak_following_error_m: f64,
    /// Largest true tool deviation away from the part (tool − reference > 0) after settling:
    /// the form error standing at the step edge, m (thesis: 106 → 27 nm).
    pub edge_form_error_m: f64,
    /// RMS following error after settling, m.
    pub following_rms_m: f64,
}

/// Runs the intermittent cut of `plan` (its scenario must be `intermittent-cut`) once per Ka,
/// with the acceleration-feedback controller (Ka = 0: its PID alone).
pub fn study(plan: &Plan, kas: &[f64]) -> Result<Vec<KaRow>, StudyError> {
    if !matches!(plan.config.scenario, Scenario::IntermittentCut { .. }) {
        return Err(plan
            .origin
            .invalid(
                "scenario.kind",
                "(not intermittent-cut)",
                "\"intermittent-cut\"",
            )
            .into());
    }
    kas.iter()
        .map(|&ka| {
            let at = plan.with_controller(ControllerConfig {
                kind: ControllerKind::Accel,
                ka,
                ..plan.config.controller.clone()
            })?;
            let settle_ns = (at.config.run.settle() * 1e9) as u64;
            let (mut peak, mut edge) = (0.0f64, 0.0f64);
            let pid_scale = at.controller.pid.kp / at.config.controller.pid.kp;
            let summary = run_to_end_with(&at, |f| {
                if f.time_ns >= settle_ns {
                    peak = peak.max((f.telemetry.following_error_m as f64).abs());
                    edge = edge.max(f.truth.true_error_m as f64);
                }
            })?;
            Ok(KaRow {
                ka,
                pid_scale,
                peak_following_error_m: peak,
                edge_form_error_m: edge,
                following_rms_m: summary.following_error_m.rms,
            })
        })
        .collect()
}
