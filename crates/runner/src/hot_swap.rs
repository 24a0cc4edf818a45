//! Controllers sent to a running loop of ours (`servo ctl load` into `servo controller`): the
//! runtime's service thread parses nothing itself here — [`PlanCheck`] builds the run with the
//! loaded controller (a state-space file as `servo synth` writes it, or a `[controller]`
//! fragment as `servo tune` writes it), checks what it was made for and the new closed loop's
//! stability on the run's plant model, and hands the runtime the controller with its gain
//! range. A daemon without the model takes only files that carry that check (the runtime's
//! own rule when [`servo_runtime::ServeOptions`] names no check).

use crate::error::RunError;
use crate::gain_range::gain_range;
use crate::plan::Plan;
use daq_io::ack_status;
use run_config::{ConfigError, ControllerConfig, ControllerKind, RunConfig};
use servo_runtime::{Refusal, Vet, Vetted};
use std::path::PathBuf;

pub use servo_config::LOADED_FILE;

/// The check of a loaded controller against the run's plant model.
pub struct PlanCheck {
    /// The run: what a loaded controller is built for and checked against.
    pub plan: Plan,
}

impl Vet for PlanCheck {
    fn vet(&self, file: &[u8]) -> Result<Vetted, Refusal> {
        let plan = &self.plan;
        let built = plan_after_load(plan, file).and_then(|p| gain_range(&p).map(|g| (p, g)));
        match built {
            Ok((p, _)) if reference_path_differs(plan, &p) => Err(Refusal::new(
                ack_status::REFUSED_INVALID,
                format!(
                    "the file changes the reference path (feedforward {:?} → {:?}, smoothing {} → {} Hz): \
                     a load swaps the feedback controller only — restart the run for another feedforward",
                    plan.config.controller.feedforward,
                    p.config.controller.feedforward,
                    plan.config.controller.smoothing_hz,
                    p.config.controller.smoothing_hz
                ),
            )),
            Ok((p, stability)) => Ok(Vetted {
                spec: p.controller.spec,
                stability,
            }),
            Err(RunError::Unstable { radius, .. }) => Err(Refusal {
                status: ack_status::REFUSED_MARGIN,
                spectral_radius: radius,
                message: "the new closed loop is unstable".into(),
            }),
            Err(e) if made_for_mismatch(&e) => Err(Refusal::new(ack_status::REFUSED_PROVENANCE, e)),
            Err(e) => Err(Refusal::new(ack_status::REFUSED_INVALID, e)),
        }
    }
}

/// Whether the run of `after` shapes the reference differently from the run of `plan`
/// (feedforward, its smoothing): the preview window those need is sized when a run starts, and
/// a swap replaces the feedback controller only — a changed feedforward would be silently
/// ignored, so it is refused.
fn reference_path_differs(plan: &Plan, after: &Plan) -> bool {
    let (a, b) = (&plan.config.controller, &after.config.controller);
    a.feedforward != b.feedforward || a.smoothing_hz != b.smoothing_hz
}

/// Whether `e` refuses a controller made for another plant or rate.
fn made_for_mismatch(e: &RunError) -> bool {
    matches!(e, RunError::Config(ConfigError::Invalid { key, .. })
        if key == "made_for" || key.ends_with(".made_for"))
}

/// The run of `plan` with the controller `file` describes — the loop a `servo ctl load` of
/// it runs after the swap: a state-space controller file (as `servo synth` writes it), or a
/// config fragment whose `[controller]` table is taken (as `servo tune` writes it). Built and
/// checked as any run (stability, made-for), nothing read from disk; a file that is not UTF-8
/// TOML of either kind is a parse error naming [`LOADED_FILE`].
pub fn plan_after_load(plan: &Plan, file: &[u8]) -> Result<Plan, RunError> {
    let parse = |message: String| {
        RunError::from(ConfigError::Parse {
            path: PathBuf::from(LOADED_FILE),
            message,
        })
    };
    let text = std::str::from_utf8(file)
        .map(|t| t.strip_prefix('\u{feff}').unwrap_or(t))
        .map_err(|e| {
            parse(format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.valid_up_to()
            ))
        })?;
    let table: toml::Table =
        toml::from_str(text).map_err(|e| parse(servo_config::toml_message(text, &e)))?;
    let (controller, bytes) = if let Some(fragment) = table.get("controller") {
        // Whether the fragment sets the reference path (a tuning fragment holds gains only).
        let has = |key: &str| fragment.get(key).is_some();
        let (sets_feedforward, sets_smoothing) = (has("feedforward"), has("smoothing_hz"));
        let config: RunConfig =
            toml::from_str(text).map_err(|e| parse(servo_config::toml_message(text, &e)))?;
        if config.controller.kind == ControllerKind::Ss {
            return Err(parse(
                "a [controller] fragment of kind ss names a file: load the file".into(),
            ));
        }
        // The reference path is the run's unless the fragment says otherwise.
        let running = &plan.config.controller;
        let controller = ControllerConfig {
            feedforward: if sets_feedforward {
                config.controller.feedforward
            } else {
                running.feedforward
            },
            smoothing_hz: if sets_smoothing {
                config.controller.smoothing_hz
            } else {
                running.smoothing_hz
            },
            ..config.controller
        };
        (controller, None)
    } else {
        let controller = ControllerConfig {
            kind: ControllerKind::Ss,
            ss_file: Some(PathBuf::from(LOADED_FILE)),
            ..plan.config.controller.clone()
        };
        (controller, Some(file.to_vec()))
    };
    plan.with_controller_file(controller, bytes)
}
