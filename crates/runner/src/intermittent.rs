//! The intermittent-cut experiment of thesis §7.6 for a list of acceleration gains: a face
//! cut over a part milled half lower, so the cutting force steps on and off twice per spindle
//! revolution; for each Ka the peak following error (Fig 7-17) and the height of the form
//! error the tool leaves at the step edge (Fig 7-19: the tool pushed away from the part
//! leaves material standing).

use crate::config::{ControllerKind, Loaded, Scenario};
use crate::run::{run_to_end_with, RunError};
use serde::Serialize;

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

/// Runs the intermittent cut of `cfg` (its scenario must be `intermittent-cut`) once per Ka,
/// with the acceleration-feedback controller (Ka = 0: its PID alone).
pub fn study(cfg: &Loaded, kas: &[f64]) -> Result<Vec<KaRow>, RunError> {
    if !matches!(cfg.config.scenario, Scenario::IntermittentCut { .. }) {
        return Err(cfg
            .invalid(
                "scenario.kind",
                "(not intermittent-cut)",
                "\"intermittent-cut\"",
            )
            .into());
    }
    kas.iter()
        .map(|&ka| {
            let mut c = cfg.clone();
            c.config.controller.kind = ControllerKind::Accel;
            c.config.controller.ka = ka;
            let settle_ns = (c.config.run.settle() * 1e9) as u64;
            let (mut peak, mut edge) = (0.0f64, 0.0f64);
            let pid_scale = {
                let ctrl = crate::controller::Controller::build(&c)?;
                ctrl.pid.kp / c.config.controller.pid.kp
            };
            let summary = run_to_end_with(&c, |f| {
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
