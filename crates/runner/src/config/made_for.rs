//! What a result was made for (provenance): the plant — the SHA-256 of its
//! parameters as TOML and a readable stage name — the servo rate and the tool version. Written
//! into controller files and tuning fragments; the run that loads them checks it and refuses a
//! mismatch with both sides named, unless told to accept it (`--force`).

use super::{presets::StagePreset, ConfigError, Origin};
use plant_sim::PlantParams;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of `data`.
pub fn sha256_hex(data: &[u8]) -> String {
    Sha256::digest(data)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The plant, rate and tool a controller (or another result) was made for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MadeFor {
    /// The tool and its version (`fts-servo 0.1.0`).
    pub tool: String,
    /// SHA-256 (hex) of the plant's dynamics as TOML (`[plant]` of the config without its
    /// noise: stage, actuator, sensors, converters, timing — what decides whether a controller
    /// is stable and does what it was designed to).
    pub plant_sha256: String,
    /// The stage, readably: `light`, `heavy` (the thesis presets) or `custom`.
    pub stage: String,
    /// The servo rate, Hz.
    pub servo_rate_hz: f64,
}

impl MadeFor {
    /// The provenance of a result made for `plant`.
    pub fn of(plant: &PlantParams) -> Self {
        let dynamics = PlantParams {
            noise: Default::default(),
            ..*plant
        };
        let text = toml::to_string(&dynamics).expect("plant parameters always serialise");
        let stage = [StagePreset::Light, StagePreset::Heavy]
            .into_iter()
            .find(|p| p.params() == plant.stage)
            .map_or("custom", |p| match p {
                StagePreset::Light => "light",
                StagePreset::Heavy => "heavy",
            });
        MadeFor {
            tool: format!("fts-servo {}", env!("CARGO_PKG_VERSION")),
            plant_sha256: sha256_hex(text.as_bytes()),
            stage: stage.into(),
            servo_rate_hz: plant.timing.servo_rate_hz,
        }
    }

    /// What the TOML file at `path` says it was made for (its `[made_for]` or
    /// `[controller.made_for]` table), described; `None` when it does not say.
    pub fn describe_file(path: &std::path::Path) -> Option<String> {
        let text = super::input_file::read_text(path).ok()?;
        let table: toml::Table = toml::from_str(&text).ok()?;
        let made_for = table.get("made_for").or_else(|| {
            table
                .get("controller")
                .and_then(|c| c.as_table())
                .and_then(|c| c.get("made_for"))
        })?;
        let m: MadeFor = made_for.clone().try_into().ok()?;
        Some(format!("made for {}", m.describe()))
    }

    /// `stage heavy at 20000 Hz, plant 1a2b3c4d…`.
    pub fn describe(&self) -> String {
        format!(
            "stage {} at {} Hz, plant {}…",
            self.stage,
            self.servo_rate_hz,
            &self.plant_sha256[..self.plant_sha256.len().min(12)]
        )
    }

    /// The `[table]` of this provenance as TOML, under `table` (`made_for`,
    /// `controller.made_for`).
    pub fn to_toml(&self, table: &str) -> String {
        format!(
            "[{table}]\n{}",
            toml::to_string(self).expect("provenance always serialises")
        )
    }

    /// Checks that a result made for `self` may run on `run` (the run's own provenance):
    /// refused, naming both, when the plant or the rate differ — unless `force`. `key` locates
    /// the provenance in `at` (the file that carries it).
    pub fn check(
        &self,
        run: &MadeFor,
        at: &Origin,
        key: &str,
        force: bool,
    ) -> Result<(), ConfigError> {
        let same_rate = (self.servo_rate_hz - run.servo_rate_hz).abs() <= 1e-6 * run.servo_rate_hz;
        if force || (self.plant_sha256 == run.plant_sha256 && same_rate) {
            return Ok(());
        }
        Err(at.invalid(
            key,
            format!("made for {}", self.describe()),
            &format!(
                "this run's plant ({}); run it on the plant it was made for (its --mass, --rate, -c), redesign it for this one, or --force (controller.force = true) to run it anyway",
                run.describe()
            ),
        ))
    }
}

/// `plant` as the `[plant…]` tables of a run config: a fragment any command takes with `-c`.
pub fn plant_toml(plant: &PlantParams) -> String {
    #[derive(Serialize)]
    struct Fragment<'a> {
        plant: &'a PlantParams,
    }
    toml::to_string(&Fragment { plant }).expect("plant parameters always serialise")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_result_for_another_stage_or_rate_is_refused_with_both_named() {
        let light = PlantParams::default();
        let mut heavy = light;
        heavy.stage = StagePreset::Heavy.params();
        let (for_light, for_heavy) = (MadeFor::of(&light), MadeFor::of(&heavy));
        assert_eq!(
            (for_light.stage.as_str(), for_heavy.stage.as_str()),
            ("light", "heavy")
        );
        let at = Origin::default();
        assert!(for_heavy.check(&for_heavy, &at, "made_for", false).is_ok());
        let e = for_heavy
            .check(&for_light, &at, "made_for", false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("stage heavy") && e.contains("stage light") && e.contains("--force"),
            "{e}"
        );
        assert!(for_heavy.check(&for_light, &at, "made_for", true).is_ok());
        let mut fast = light;
        fast.timing.servo_rate_hz = 20_000.0;
        let e = MadeFor::of(&fast)
            .check(&for_light, &at, "made_for", false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("20000 Hz") && e.contains("199600 Hz"), "{e}");
        // The noise is not the plant's dynamics: a controller runs with the noise off.
        let mut quiet = heavy;
        (quiet.noise.sensor, quiet.noise.current) = (false, false);
        assert_eq!(MadeFor::of(&quiet), for_heavy);
        // A TOML round trip keeps it.
        let text = for_heavy.to_toml("made_for");
        #[derive(Deserialize)]
        struct File {
            made_for: MadeFor,
        }
        let back: File = toml::from_str(&text).unwrap();
        assert_eq!(back.made_for, for_heavy);
    }
}
