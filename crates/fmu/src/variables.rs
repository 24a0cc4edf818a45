//! The variables of each unit, with their value references, causality, unit and range: the
//! one table the model description is written from and libfts_fmu serves.

use crate::units::unit_of;
use plant_sim::limits::limit_of;
use plant_sim::PlantParams;
use serde_json::Value;

/// Which unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The simulated stage: the DAC command and a force in, the readings out.
    Stage,
    /// The controller of a deployment: the readings in, the DAC command out.
    Controller,
}

/// A variable's type (FMI 2 name; FMI 3: Float64, Int32, Boolean, String).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum VarType {
    /// A real number.
    Real,
    /// A 32-bit signed integer.
    Integer,
    /// A Boolean.
    Boolean,
    /// A string.
    String,
}

/// What a variable is to the importer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// Set by the importer at any communication point.
    Input,
    /// Read by the importer.
    Output,
    /// Set before initialisation, fixed after.
    Parameter,
    /// Computed from the parameters at initialisation.
    CalculatedParameter,
}

/// A start value.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    /// A real start value.
    Real(f64),
    /// An integer start value.
    Integer(i32),
    /// A Boolean start value.
    Boolean(bool),
    /// A string start value.
    String(String),
}

/// One variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Name (`dac_v`, `plant.stage.m1_kg`).
    pub name: String,
    /// Value reference.
    pub vr: u32,
    /// Type.
    pub ty: VarType,
    /// Causality.
    pub causality: Causality,
    /// Start value (None for outputs and calculated parameters).
    pub start: Option<Start>,
    /// Smallest allowed value (reals and integers).
    pub min: Option<f64>,
    /// Largest allowed value.
    pub max: Option<f64>,
    /// The allowed range as an error states it, with its unit (`[1e-6, 1e3] kg`).
    pub range: Option<String>,
    /// What it is, with its unit.
    pub description: String,
    /// For outputs: the inputs (value references) the output depends on within a step.
    pub depends_on: Vec<u32>,
}

impl Variable {
    fn new(name: &str, vr: u32, ty: VarType, causality: Causality, description: &str) -> Self {
        Variable {
            name: name.to_owned(),
            vr,
            ty,
            causality,
            start: None,
            min: None,
            max: None,
            range: None,
            description: description.to_owned(),
            depends_on: Vec::new(),
        }
    }

    fn start(mut self, start: Start) -> Self {
        self.start = Some(start);
        self
    }
}

/// The stage's value references.
pub mod stage {
    /// Input: the DAC command held over the step, V.
    pub const DAC_V: u32 = 1;
    /// Input: an external force on the tool (cutting, a disturbance), N.
    pub const FORCE_N: u32 = 2;
    /// Output: the gap (capacitive sensor) reading, V.
    pub const GAP_V: u32 = 3;
    /// Output: the accelerometer reading, V.
    pub const ACCEL_V: u32 = 4;
    /// Output: the true tool position, m.
    pub const TOOL_POSITION_M: u32 = 5;
    /// Output: the reading's contract flags.
    pub const FLAGS: u32 = 6;
    /// Parameter: the noise seed (`run.seed`).
    pub const SEED: u32 = 7;
    /// Calculated parameter: the plant's dynamics digest (SHA-256 hex).
    pub const PLANT_SHA256: u32 = 8;
    /// The first plant parameter's value reference; the others follow in the table's order.
    pub const FIRST_PLANT_PARAMETER: u32 = 100;
}

/// The controller's value references.
pub mod controller {
    /// Input: the gap reading, V.
    pub const GAP_V: u32 = 1;
    /// Input: the accelerometer reading, V.
    pub const ACCEL_V: u32 = 2;
    /// Input: the reading's contract flags.
    pub const READING_FLAGS: u32 = 3;
    /// Output: the DAC command, V.
    pub const DAC_V: u32 = 4;
    /// Output: the tick's reference position, m.
    pub const REFERENCE_M: u32 = 5;
    /// Output: the measured position the tick acted on, m.
    pub const MEASURED_M: u32 = 6;
    /// Output: reference − measured, m.
    pub const FOLLOWING_ERROR_M: u32 = 7;
    /// Output: the tick's telemetry flags (saturation, trip and its cause).
    pub const FLAGS: u32 = 8;
    /// Output: the loop is tripped (in its safe state).
    pub const TRIPPED: u32 = 9;
    /// Parameter: the plant digest of the stage it runs on ("": not checked).
    pub const PLANT_SHA256: u32 = 10;
}

/// The largest seed an FMI 2 Integer carries.
pub const MAX_SEED: u64 = i32::MAX as u64;

/// A plant parameter's value as the unit holds it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scalar {
    /// A real.
    Real(f64),
    /// An integer.
    Integer(i64),
    /// A Boolean.
    Boolean(bool),
}

/// Every scalar of `plant` as (dotted key under `[plant]`, value), in the file's order (the
/// current-loop model's name and the extra modes are not parameters of a unit).
pub fn plant_scalars(plant: &PlantParams) -> Vec<(String, Scalar)> {
    fn walk(prefix: &str, v: &Value, out: &mut Vec<(String, Scalar)>) {
        match v {
            Value::Object(map) => {
                for (k, v) in map {
                    let key = if prefix.is_empty() {
                        k.clone()
                    } else {
                        format!("{prefix}.{k}")
                    };
                    walk(&key, v, out);
                }
            }
            Value::Bool(b) => out.push((prefix.to_owned(), Scalar::Boolean(*b))),
            Value::Number(n) if n.is_f64() => out.push((
                prefix.to_owned(),
                Scalar::Real(n.as_f64().unwrap_or(f64::NAN)),
            )),
            Value::Number(n) => out.push((
                prefix.to_owned(),
                Scalar::Integer(n.as_i64().unwrap_or(i64::MAX)),
            )),
            _ => {}
        }
    }
    let mut out = Vec::new();
    let value = serde_json::to_value(plant).expect("plant parameters always serialise");
    walk("", &value, &mut out);
    out
}

/// The plant scalars a stage unit offers as parameters: every one of [`plant_scalars`] but the
/// servo rate, which fixes the unit's tick (its description's step).
pub fn plant_parameters(plant: &PlantParams) -> Vec<(String, Scalar)> {
    plant_scalars(plant)
        .into_iter()
        .filter(|(key, _)| key != "timing.servo_rate_hz")
        .collect()
}

/// The largest external force on the tool a stage unit takes, N (either sign).
pub const MAX_FORCE_N: f64 = 1e3;

/// `base` with the scalars `values` (keys as [`plant_scalars`] gives them) put in.
pub fn plant_with(base: &PlantParams, values: &[(String, Scalar)]) -> Result<PlantParams, String> {
    let mut value = serde_json::to_value(base).map_err(|e| e.to_string())?;
    for (key, scalar) in values {
        let slot = value
            .pointer_mut(&format!("/{}", key.replace('.', "/")))
            .ok_or_else(|| format!("plant.{key}: no such parameter"))?;
        *slot = match *scalar {
            Scalar::Real(x) => serde_json::Number::from_f64(x)
                .map(Value::Number)
                .ok_or_else(|| format!("plant.{key} = {x}: not a finite number"))?,
            Scalar::Integer(i) => Value::from(i),
            Scalar::Boolean(b) => Value::Bool(b),
        };
    }
    serde_json::from_value(value).map_err(|e| format!("plant: {e}"))
}

/// The variables of a stage unit whose plant and seed are `plant` and `seed`.
pub fn stage_variables(plant: &PlantParams, seed: u64) -> Vec<Variable> {
    use stage::*;
    let real = |name, vr, causality, description| {
        Variable::new(name, vr, VarType::Real, causality, description)
    };
    let mut out = vec![
        real(
            "dac_v",
            DAC_V,
            Causality::Input,
            "DAC command held over the step, V",
        )
        .start(Start::Real(0.0)),
        Variable {
            min: Some(-MAX_FORCE_N),
            max: Some(MAX_FORCE_N),
            range: Some(format!("[-{MAX_FORCE_N:e}, {MAX_FORCE_N:e}] N")),
            ..real(
                "force_n",
                FORCE_N,
                Causality::Input,
                "External force on the tool (cutting, a disturbance), N, positive away from the workpiece",
            )
            .start(Start::Real(0.0))
        },
        real(
            "gap_v",
            GAP_V,
            Causality::Output,
            "Gap (capacitive sensor) reading at the end of the step, V, as the ADC delivers it",
        ),
        real(
            "accel_v",
            ACCEL_V,
            Causality::Output,
            "Accelerometer reading at the end of the step, V, as the ADC delivers it",
        ),
        real(
            "tool_position_m",
            TOOL_POSITION_M,
            Causality::Output,
            "True tool position relative to the frame at the end of the step, m (not measurable on a real stage)",
        ),
        Variable::new(
            "flags",
            FLAGS,
            VarType::Integer,
            Causality::Output,
            "The reading's contract flags (1: gap clipped, 2: accelerometer clipped, 4: DAC clipped)",
        ),
        Variable {
            min: Some(0.0),
            max: Some(MAX_SEED as f64),
            range: Some(format!("[0, {MAX_SEED}]")),
            ..Variable::new(
                "seed",
                SEED,
                VarType::Integer,
                Causality::Parameter,
                "Noise seed (run.seed)",
            )
            .start(Start::Integer(seed.min(MAX_SEED) as i32))
        },
        Variable::new(
            "plant_sha256",
            PLANT_SHA256,
            VarType::String,
            Causality::CalculatedParameter,
            "SHA-256 of the plant's dynamics: give it to the controller unit's plant_sha256 to check its deployment was made for this stage",
        ),
    ];
    for (i, (key, value)) in plant_parameters(plant).into_iter().enumerate() {
        let name = format!("plant.{key}");
        let vr = FIRST_PLANT_PARAMETER + i as u32;
        let limit = limit_of(&key);
        let unit = unit_of(&key).map_or(String::new(), |u| format!(", {}", u.name));
        let description = match limit {
            Some(l) => format!("[plant] {key}{unit}; allowed {}", l.range),
            None => format!("[plant] {key}{unit}"),
        };
        let (ty, start) = match value {
            Scalar::Real(x) => (VarType::Real, Start::Real(x)),
            Scalar::Integer(n) => (VarType::Integer, Start::Integer(n as i32)),
            Scalar::Boolean(b) => (VarType::Boolean, Start::Boolean(b)),
        };
        out.push(Variable {
            min: limit.map(|l| l.min),
            max: limit.map(|l| l.max),
            range: limit.map(|l| l.range.to_owned()),
            ..Variable::new(&name, vr, ty, Causality::Parameter, &description).start(start)
        });
    }
    out
}

/// The variables of a controller unit.
pub fn controller_variables() -> Vec<Variable> {
    use controller::*;
    let inputs = vec![GAP_V, ACCEL_V, READING_FLAGS];
    let output = |name, vr, ty, description| Variable {
        depends_on: inputs.clone(),
        ..Variable::new(name, vr, ty, Causality::Output, description)
    };
    let input = |name, vr, ty, description, start| {
        Variable::new(name, vr, ty, Causality::Input, description).start(start)
    };
    vec![
        input(
            "gap_v",
            GAP_V,
            VarType::Real,
            "Gap (capacitive sensor) reading of this tick, V",
            Start::Real(0.0),
        ),
        input(
            "accel_v",
            ACCEL_V,
            VarType::Real,
            "Accelerometer reading of this tick, V",
            Start::Real(0.0),
        ),
        Variable {
            min: Some(0.0),
            max: Some(255.0),
            range: Some("[0, 255] (the reading's flag bits)".into()),
            ..input(
                "reading_flags",
                READING_FLAGS,
                VarType::Integer,
                "The reading's contract flags (the stage unit's flags)",
                Start::Integer(0),
            )
        },
        output(
            "dac_v",
            DAC_V,
            VarType::Real,
            "DAC command of this tick, V: computed from this communication point's readings, to be held over the step",
        ),
        output(
            "reference_m",
            REFERENCE_M,
            VarType::Real,
            "Reference position of the tick (the deployment's reference), m",
        ),
        output(
            "measured_m",
            MEASURED_M,
            VarType::Real,
            "Measured position the tick acted on (gap reading / sensitivity), m",
        ),
        output(
            "following_error_m",
            FOLLOWING_ERROR_M,
            VarType::Real,
            "Following error reference - measured, m",
        ),
        output(
            "flags",
            FLAGS,
            VarType::Integer,
            "The tick's contract flags (256: saturated, 512: tripped, 1024-16384: the trip's cause)",
        ),
        output(
            "tripped",
            TRIPPED,
            VarType::Boolean,
            "The loop has tripped to its safe state (it stays there)",
        ),
        Variable::new(
            "plant_sha256",
            PLANT_SHA256,
            VarType::String,
            Causality::Parameter,
            "The stage unit's plant_sha256: the deployment must have been made for it (\"\": not checked)",
        )
        .start(Start::String(String::new())),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plant_scalars_round_trip_and_carry_their_limits() {
        let plant = PlantParams::heavy();
        let scalars = plant_scalars(&plant);
        assert!(scalars.len() > 40, "{} scalars", scalars.len());
        assert_eq!(plant_parameters(&plant).len(), scalars.len() - 1);
        assert_eq!(
            plant_with(&PlantParams::default(), &scalars).unwrap(),
            plant
        );
        let vars = stage_variables(&plant, 7);
        let m2 = vars.iter().find(|v| v.name == "plant.stage.m2_kg").unwrap();
        assert_eq!(m2.start, Some(Start::Real(0.170)));
        assert_eq!((m2.min, m2.max), (Some(1e-6), Some(1e3)));
        let bits = vars.iter().find(|v| v.name == "plant.adc.bits").unwrap();
        assert_eq!(
            (bits.ty, bits.start.clone()),
            (VarType::Integer, Some(Start::Integer(16)))
        );
        let noise = vars
            .iter()
            .find(|v| v.name == "plant.noise.sensor")
            .unwrap();
        assert_eq!(noise.ty, VarType::Boolean);
        assert!(vars.iter().all(|v| v.name != "plant.timing.servo_rate_hz"));
        let mut vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
        vrs.sort_unstable();
        vrs.dedup();
        assert_eq!(vrs.len(), vars.len(), "value references are unique");
    }
}
