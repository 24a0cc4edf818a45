//! A plant on its own: a TOML file holding only a `[plant]` table — the model `servo identify`
//! writes, or a lab's description of its stage — that replaces the configured plant
//! (`--plant model.toml`). Checked when read, so its errors name its own file and line.

use super::{input_file, ConfigError, Origin};
use plant_sim::cutting::CuttingProfile;
use plant_sim::model::ModelError;
use plant_sim::sim::SimError;
use plant_sim::{PlantParams, Simulator};
use serde::Deserialize;
use std::path::Path;

/// The file's one table.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PlantFile {
    plant: PlantParams,
}

/// Reads the plant of `path` (a `[plant]` table and nothing else; keys not given take the
/// thesis defaults) and checks every parameter's range. Errors name the file, line and key.
pub fn read_plant_file(path: &Path) -> Result<PlantParams, ConfigError> {
    let text = input_file::read_text(path)?;
    let file: PlantFile = toml::from_str(&text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: format!(
            "a plant file holds one [plant] table: {}",
            servo_config::toml_message(&text, &e)
        ),
    })?;
    let at = Origin {
        path: Some(path.to_owned()),
        text: Some(text),
    };
    match Simulator::new(&file.plant, 0, &CuttingProfile::default()) {
        Ok(_) => Ok(file.plant),
        Err(SimError::Model(ModelError::Parameter { key, value, range })) => {
            Err(at.invalid(&format!("plant.{key}"), value, &range))
        }
        Err(other) => Err(at.invalid(
            "plant",
            "(this table)",
            &format!("a plant the simulator builds ({other})"),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant_toml;

    /// `text` as file `name` in `dir` (a private folder of the test's own).
    fn write(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn a_written_plant_reads_back_equal() {
        let mut plant = PlantParams::default();
        plant.stage.m1_kg *= 1.07;
        plant.stage.k2_n_per_m *= 0.93;
        let dir = tempfile::tempdir().unwrap();
        let p = write(&dir, "model.toml", &plant_toml(&plant));
        assert_eq!(read_plant_file(&p).unwrap(), plant);
    }

    #[test]
    fn other_tables_and_bad_values_are_refused_with_file_and_key() {
        let dir = tempfile::tempdir().unwrap();
        let p = write(&dir, "run.toml", "[run]\nduration_s = 1.0\n");
        let e = read_plant_file(&p).unwrap_err().to_string();
        assert!(e.contains("run.toml") && e.contains("[plant]"), "{e}");
        let p = write(&dir, "bad.toml", "[plant.stage]\nm1_kg = -1.0\n");
        let e = read_plant_file(&p).unwrap_err().to_string();
        assert!(
            e.contains("bad.toml:2") && e.contains("plant.stage.m1_kg") && e.contains("1e-6"),
            "{e}"
        );
    }
}
