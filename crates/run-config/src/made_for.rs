//! What a result was made for (provenance), as the run sees it: the plant's hash of its
//! parameters as TOML, its stage name, the servo rate and the tool version
//! ([`servo_config::MadeFor`]); checked where a run loads a result, a mismatch refused with
//! both sides named unless the configuration accepts it (`controller.force`).

use super::{presets::StagePreset, ConfigError, Origin};
use plant_sim::PlantParams;
use serde::Serialize;
use servo_config::MadeFor;
use sha2::{Digest, Sha256};

/// Lower-case hex SHA-256 of `data`.
pub fn sha256_hex(data: &[u8]) -> String {
    Sha256::digest(data)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The provenance of a result made for `plant`.
pub fn made_for_plant(plant: &PlantParams) -> MadeFor {
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
pub fn describe_made_for(path: &std::path::Path) -> Option<String> {
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

/// Checks that a result made for `made_for` may run on `run` (the run's own provenance):
/// refused, naming both, when the plant or the rate differ — unless `force`. `key` locates the
/// provenance in `at` (the file that carries it).
pub fn check_made_for(
    made_for: &MadeFor,
    run: &MadeFor,
    at: &Origin,
    key: &str,
    force: bool,
) -> Result<(), ConfigError> {
    if force {
        return Ok(());
    }
    made_for.check(run).map_err(|e| {
        at.invalid(
            key,
            format!("made for {}", e.made_for.describe()),
            &format!(
                "this run's plant ({}); run it on the plant it was made for, redesign it for this one, or set controller.force = true to run it anyway",
                e.run.describe()
            ),
        )
    })
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
        let (for_light, for_heavy) = (made_for_plant(&light), made_for_plant(&heavy));
        assert_eq!(
            (for_light.stage.as_str(), for_heavy.stage.as_str()),
            ("light", "heavy")
        );
        let at = Origin::default();
        assert!(check_made_for(&for_heavy, &for_heavy, &at, "made_for", false).is_ok());
        let e = check_made_for(&for_heavy, &for_light, &at, "made_for", false)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("stage heavy")
                && e.contains("stage light")
                && e.contains("controller.force"),
            "{e}"
        );
        assert!(check_made_for(&for_heavy, &for_light, &at, "made_for", true).is_ok());
        let mut fast = light;
        fast.timing.servo_rate_hz = 20_000.0;
        let e = check_made_for(&made_for_plant(&fast), &for_light, &at, "made_for", false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("20000 Hz") && e.contains("199600 Hz"), "{e}");
        // The noise is not the plant's dynamics: a controller runs with the noise off.
        let mut quiet = heavy;
        (quiet.noise.sensor, quiet.noise.current) = (false, false);
        assert_eq!(made_for_plant(&quiet), for_heavy);
        // A TOML round trip keeps it.
        let text = for_heavy.to_toml("made_for");
        #[derive(serde::Deserialize)]
        struct File {
            made_for: MadeFor,
        }
        let back: File = toml::from_str(&text).unwrap();
        assert_eq!(back.made_for, for_heavy);
    }
}
