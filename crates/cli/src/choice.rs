//! Flags whose values are a configuration enum's names: the names a configuration file uses
//! (the enum's serde names), each with its variant's documentation as help, read from the
//! enum's JSON schema. The libraries' enums carry no command-line code of their own.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::Value;

/// The value parser of a flag taking one of `T`'s names (e.g. `--mass heavy`).
pub fn choice<T>() -> impl TypedValueParser<Value = T>
where
    T: DeserializeOwned + JsonSchema + Clone + Send + Sync + 'static,
{
    PossibleValuesParser::new(possible_values::<T>())
        .try_map(|name| serde_json::from_value::<T>(Value::String(name)))
}

/// The name a configuration file (and the flag) uses for `value`.
pub fn name_of<T: Serialize>(value: &T) -> String {
    match serde_json::to_value(value) {
        Ok(Value::String(s)) => s,
        _ => String::new(),
    }
}

/// `T`'s names with their help: the schema's `oneOf`, a documented constant per variant (the
/// workspace denies missing docs, so every variant has its description).
fn possible_values<T: JsonSchema>() -> Vec<PossibleValue> {
    let schema = serde_json::to_value(schemars::schema_for!(T)).unwrap_or_default();
    let named = |v: &Value| -> Option<PossibleValue> {
        let name = v.get("const")?.as_str()?;
        let value = PossibleValue::new(name.to_owned());
        Some(match v.get("description").and_then(Value::as_str) {
            Some(doc) => value.help(first_paragraph(doc)),
            None => value,
        })
    };
    match schema.get("oneOf") {
        Some(Value::Array(variants)) => variants.iter().filter_map(named).collect(),
        _ => Vec::new(),
    }
}

/// A doc comment's first paragraph on one line, without its closing full stop (as a flag's
/// own help shows).
fn first_paragraph(doc: &str) -> String {
    let first = doc.split("\n\n").next().unwrap_or_default();
    let line = first.split_whitespace().collect::<Vec<_>>().join(" ");
    line.strip_suffix('.').unwrap_or(&line).to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use run_config::presets::{ScenarioKind, StagePreset};
    use run_config::{FeedforwardKind, SafeState};

    /// The names a flag offers are the names a configuration file takes, each parsed to its
    /// variant, with the variant's documentation as help.
    #[test]
    fn a_flag_offers_the_configuration_names_with_their_documentation() {
        let names = |v: Vec<PossibleValue>| -> Vec<String> {
            v.iter().map(|p| p.get_name().to_owned()).collect()
        };
        assert_eq!(names(possible_values::<StagePreset>()), ["light", "heavy"]);
        assert_eq!(
            names(possible_values::<FeedforwardKind>()),
            ["none", "model", "zpetc", "zpetc-sensor", "fir"]
        );
        let scenario = possible_values::<ScenarioKind>();
        assert!(names(scenario.clone()).contains(&"intermittent-cut".to_owned()));
        let help = scenario[0].get_help().map(ToString::to_string);
        assert_eq!(help.as_deref(), Some("Hold position (§5.7.3)"));
        let cmd = clap::Command::new("t").arg(
            clap::Arg::new("s")
                .long("safe-state")
                .value_parser(choice::<SafeState>()),
        );
        let m = cmd
            .clone()
            .try_get_matches_from(["t", "--safe-state", "hold"])
            .unwrap();
        assert_eq!(m.get_one::<SafeState>("s"), Some(&SafeState::Hold));
        assert!(cmd
            .try_get_matches_from(["t", "--safe-state", "Hold"])
            .is_err());
        assert_eq!(name_of(&FeedforwardKind::ZpetcSensor), "zpetc-sensor");
    }
}
