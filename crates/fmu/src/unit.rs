//! A unit's own resource file (`resources/unit.toml`) and the archive contents of each kind.

use crate::description::{model_description, Header};
use crate::package::UnitFiles;
use crate::variables::{controller_variables, stage_variables, Kind};
use crate::{token, FmiVersion, DEPLOYMENT_FILE, UNIT_FILE};
use plant_sim::PlantParams;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The model identifier (binary name) of the stage unit.
pub const STAGE_IDENTIFIER: &str = "fts_stage";
/// The model identifier (binary name) of the controller unit.
pub const CONTROLLER_IDENTIFIER: &str = "fts_controller";
/// The largest resource file a unit reads, bytes.
const MAX_RESOURCE_BYTES: u64 = 4 << 20;

/// `resources/unit.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UnitConfig {
    /// `stage` or `controller`.
    pub kind: String,
    /// The stage's noise seed (the `seed` parameter's start value).
    #[serde(default)]
    pub seed: u64,
    /// The stage's plant (the `plant.…` parameters' start values).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub plant: Option<PlantParams>,
}

impl UnitConfig {
    /// Which unit.
    pub fn kind(&self) -> Result<Kind, String> {
        match self.kind.as_str() {
            "stage" => Ok(Kind::Stage),
            "controller" => Ok(Kind::Controller),
            other => Err(format!(
                "{UNIT_FILE}: kind = {other:?}: allowed \"stage\" or \"controller\""
            )),
        }
    }
}

/// A unit's resources as read by its binary.
#[derive(Debug, Clone)]
pub struct Resources {
    /// `unit.toml`.
    pub unit: UnitConfig,
    /// `deployment.toml`'s text (the controller's).
    pub deployment: Option<String>,
}

/// The bytes of the resource `path` (a regular file of at most [`MAX_RESOURCE_BYTES`]; None when
/// it is not there).
fn read_bounded(path: &Path) -> Result<Option<Vec<u8>>, String> {
    match daq_io::input_file::read_regular(path, MAX_RESOURCE_BYTES) {
        Ok(bytes) => Ok(Some(bytes)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(format!("{}: {e}", path.display())),
    }
}

/// Reads the resources in the folder `dir` and checks them against the instantiation token
/// `expected` (the description's): resources from another archive are refused.
pub fn read_resources(dir: &Path, expected: &str) -> Result<Resources, String> {
    let unit_path = dir.join(UNIT_FILE);
    let unit_bytes = read_bounded(&unit_path)?.ok_or_else(|| {
        format!(
            "{}: missing (not an fts-servo unit's resources)",
            unit_path.display()
        )
    })?;
    let deployment = read_bounded(&dir.join(DEPLOYMENT_FILE))?;
    let found = token(&unit_bytes, deployment.as_deref());
    if found != expected {
        return Err(format!(
            "the resources in {} are not this description's (instantiation token {expected}, resources {found})",
            dir.display()
        ));
    }
    let text =
        String::from_utf8(unit_bytes).map_err(|e| format!("{}: {e}", unit_path.display()))?;
    let unit: UnitConfig =
        toml::from_str(&text).map_err(|e| format!("{}: {e}", unit_path.display()))?;
    let deployment = deployment
        .map(String::from_utf8)
        .transpose()
        .map_err(|e| format!("{DEPLOYMENT_FILE}: {e}"))?;
    Ok(Resources { unit, deployment })
}

/// The archive contents of the stage unit of `plant` with noise seed `seed`, its default
/// experiment `stop_s` long.
pub fn stage_files(version: FmiVersion, plant: &PlantParams, seed: u64, stop_s: f64) -> UnitFiles {
    let unit = toml::to_string(&UnitConfig {
        kind: "stage".into(),
        seed,
        plant: Some(*plant),
    })
    .expect("a unit's configuration always serialises");
    let header = Header {
        model_name: "fts-servo stage".into(),
        model_identifier: STAGE_IDENTIFIER.into(),
        description: format!(
            "The fast tool servo's simulated stage (four-mass flexure, current loop, capacitive sensor, accelerometer, ADC/DAC, delay, noise), stepped in whole servo ticks of {} s; binary for x86-64 Linux",
            plant.period_s()
        ),
        token: token(unit.as_bytes(), None),
        step_s: plant.period_s(),
        stop_s,
    };
    UnitFiles {
        version,
        model_identifier: STAGE_IDENTIFIER.into(),
        model_description: model_description(version, &header, &stage_variables(plant, seed)),
        unit,
        deployment: None,
    }
}

/// The archive contents of the controller unit of the deployment `deployment` (its text, as
/// `servo deploy` writes it) whose tick is `period_s`.
pub fn controller_files(
    version: FmiVersion,
    deployment: &str,
    period_s: f64,
    stop_s: f64,
) -> UnitFiles {
    let unit = toml::to_string(&UnitConfig {
        kind: "controller".into(),
        seed: 0,
        plant: None,
    })
    .expect("a unit's configuration always serialises");
    let header = Header {
        model_name: "fts-servo controller".into(),
        model_identifier: CONTROLLER_IDENTIFIER.into(),
        description: format!(
            "The fast tool servo's controller of a deployment (servo-runtime's Servo: reference, feedforward, feedback, protection), one tick of {period_s} s per step; binary for x86-64 Linux"
        ),
        token: token(unit.as_bytes(), Some(deployment.as_bytes())),
        step_s: period_s,
        stop_s,
    };
    UnitFiles {
        version,
        model_identifier: CONTROLLER_IDENTIFIER.into(),
        model_description: model_description(version, &header, &controller_variables()),
        unit,
        deployment: Some(deployment.to_owned()),
    }
}
