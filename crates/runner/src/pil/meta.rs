//! What a PIL run measured on the target, in its summary and its recording.

use super::TargetModel;
use std::collections::BTreeMap;

/// What a PIL run measured on the target (its summary's `meta.target`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetMeta {
    /// Where the controller ran.
    pub machine: String,
    /// The firmware's build: `cortex-m7: f64 in hardware (FPv5-D16)` or the thumbv7em
    /// default's `f64 in software`.
    pub build: String,
    /// The firmware file.
    pub firmware: String,
    /// Guest instructions of a tick (`Servo::tick` in the interrupt, not its entry or the
    /// reply's copy), mean over the run.
    pub instructions_per_tick_mean: f64,
    /// The most guest instructions one tick took.
    pub instructions_per_tick_max: f64,
    /// Every instruction the target ran from READY to its report (ticks, the link, waiting)
    /// divided by the ticks: what work moved out of the timed tick would show in.
    #[serde(default)]
    pub instructions_per_tick_run: f64,
    /// The worst tick as time on the modelled part, s (at the assumed cycles per instruction,
    /// an estimate).
    pub tick_max_s: f64,
    /// The modelled part's clock, Hz.
    pub clock_hz: f64,
    /// Cycles per instruction assumed.
    pub cycles_per_instruction: f64,
    /// Ticks whose time on the part exceeded the budget share of the period.
    pub over_budget_ticks: u64,
    /// Deepest stack use on the target while the loop ran, bytes (the painted stack's
    /// high-water mark).
    pub stack_used_bytes: u32,
    /// Deepest stack use while the target built the loop from the image, bytes.
    #[serde(default)]
    pub load_stack_bytes: u32,
    /// The stack the firmware reserves, bytes.
    #[serde(default)]
    pub stack_bytes: u32,
    /// Why the link to the target was lost, if it was.
    pub lost: Option<String>,
}

/// A PIL run's facts for its recording's `end` record (what it measured on the target).
pub fn end_facts(t: &TargetMeta) -> Vec<(String, String)> {
    let mut facts = vec![
        (
            "target_instructions_per_tick_mean".to_string(),
            t.instructions_per_tick_mean.to_string(),
        ),
        (
            "target_instructions_per_tick_max".to_string(),
            t.instructions_per_tick_max.to_string(),
        ),
        (
            "target_instructions_per_tick_run".to_string(),
            t.instructions_per_tick_run.to_string(),
        ),
        ("target_clock_hz".to_string(), t.clock_hz.to_string()),
        (
            "target_cycles_per_instruction".to_string(),
            t.cycles_per_instruction.to_string(),
        ),
        (
            "target_over_budget_ticks".to_string(),
            t.over_budget_ticks.to_string(),
        ),
        (
            "target_stack_used_bytes".to_string(),
            t.stack_used_bytes.to_string(),
        ),
        (
            "target_load_stack_bytes".to_string(),
            t.load_stack_bytes.to_string(),
        ),
        ("target_stack_bytes".to_string(), t.stack_bytes.to_string()),
    ];
    if let Some(why) = &t.lost {
        facts.push(("target_lost".to_string(), why.clone()));
    }
    facts
}

impl TargetMeta {
    /// What a recording's `environment` and `end` records say of a PIL run (None for a run
    /// whose controller ran in process; numbers missing from an unfinished file read 0).
    pub fn from_records(
        environment: &BTreeMap<String, String>,
        end: &BTreeMap<String, String>,
    ) -> Option<Self> {
        let machine = environment.get("controller_on")?.clone();
        let text = |k: &str| environment.get(k).cloned().unwrap_or_default();
        let number = |k: &str| {
            end.get(k)
                .and_then(|v| v.parse::<f64>().ok())
                .unwrap_or(0.0)
        };
        let max = number("target_instructions_per_tick_max");
        let model = TargetModel {
            clock_hz: number("target_clock_hz"),
            cycles_per_instruction: number("target_cycles_per_instruction"),
            ..TargetModel::default()
        };
        Some(TargetMeta {
            machine,
            build: text("target_build"),
            firmware: text("target_firmware"),
            instructions_per_tick_mean: number("target_instructions_per_tick_mean"),
            instructions_per_tick_max: max,
            instructions_per_tick_run: number("target_instructions_per_tick_run"),
            tick_max_s: if model.clock_hz > 0.0 {
                model.seconds(max)
            } else {
                0.0
            },
            clock_hz: model.clock_hz,
            cycles_per_instruction: model.cycles_per_instruction,
            over_budget_ticks: number("target_over_budget_ticks") as u64,
            stack_used_bytes: number("target_stack_used_bytes") as u32,
            load_stack_bytes: number("target_load_stack_bytes") as u32,
            stack_bytes: number("target_stack_bytes") as u32,
            lost: end.get("target_lost").cloned(),
        })
    }
}
