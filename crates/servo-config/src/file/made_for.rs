//! What a result was made for (provenance): the plant — the SHA-256 of its parameters and a
//! readable stage name — the servo rate and the tool version. Written into deployments,
//! controller files and tuning fragments; a loop that loads one checks it and refuses a
//! mismatch with both sides named, unless told to accept it (`controller.force`).

use serde::{Deserialize, Serialize};

/// The plant, rate and tool a controller (or another result) was made for.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MadeFor {
    /// The tool and its version (`fts-servo 0.1.0`).
    pub tool: String,
    /// SHA-256 (hex) of the plant's dynamics as TOML (`[plant]` of a run configuration without
    /// its noise: what decides whether a controller is stable and does what it was designed
    /// to).
    pub plant_sha256: String,
    /// The stage, readably: `light`, `heavy` (the thesis presets) or `custom`.
    pub stage: String,
    /// The servo rate, Hz.
    pub servo_rate_hz: f64,
}

/// A result made for another plant or rate than the loop's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("made for {}; this loop's plant is {} (redesign it for this plant, or set controller.force = true to run it anyway)", made_for.describe(), run.describe())]
pub struct Mismatch {
    /// What the result was made for.
    pub made_for: Box<MadeFor>,
    /// What the loop runs on.
    pub run: Box<MadeFor>,
}

impl MadeFor {
    /// `stage heavy at 20000 Hz, plant 1a2b3c4d…`.
    pub fn describe(&self) -> String {
        format!(
            "stage {} at {} Hz, plant {}…",
            self.stage,
            self.servo_rate_hz,
            self.plant_sha256.chars().take(12).collect::<String>()
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

    /// Whether a result made for `self` may run on `run` (the loop's own provenance): the
    /// same plant and rate.
    pub fn check(&self, run: &MadeFor) -> Result<(), Mismatch> {
        let same_rate = (self.servo_rate_hz - run.servo_rate_hz).abs() <= 1e-6 * run.servo_rate_hz;
        if self.plant_sha256 == run.plant_sha256 && same_rate {
            Ok(())
        } else {
            Err(Mismatch {
                made_for: Box::new(self.clone()),
                run: Box::new(run.clone()),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::MadeFor;

    /// A digest as a file gives it, not as we write it: the description cuts characters, not
    /// bytes (found by fuzzing controller files: a character across byte 12 panicked).
    #[test]
    fn a_foreign_digest_is_described_by_its_characters() {
        let m = MadeFor {
            tool: "fts-servo".into(),
            plant_sha256: "0123456789aé€xyz".into(),
            stage: "light".into(),
            servo_rate_hz: 1.0,
        };
        assert_eq!(m.describe(), "stage light at 1 Hz, plant 0123456789aé…");
    }
}
