//! The run configuration's JSON Schema (`servo config --schema`, and the book's configuration
//! reference made from it). Each key's type, default, allowed names and description come from
//! the configuration types themselves (schemars reads their doc comments and serde
//! attributes); each number's allowed range comes from the checks a run makes: the key is set
//! to NaN in a run of each scenario kind and surface in turn, and the refusal names the range
//! (`x-allowed`). A number no check refuses is marked `x-allowed: null`.

use crate::plan::{Plan, PRESCRIPTION_INPUT, SURFACE_INPUT};
use crate::RunError;
use recorder::Input;
use run_config::presets::{ImageMap, ScenarioKind, ScenarioValues, SurfacePreset};
use run_config::{ConfigError, Loaded, Machining, Origin, RunConfig, Scenario, SurfaceConfig};
use serde_json::Value;

/// The JSON Schema (draft 2020-12) of a run configuration, with `x-allowed` on every number
/// a run checks.
pub fn schema() -> Value {
    let mut schema = serde_json::to_value(schemars::schema_for!(RunConfig))
        .expect("a JSON Schema always serialises");
    let mut leaves = Vec::new();
    walk(&schema, "", "", None, &mut leaves);
    let bases = base_configs();
    let image = probe_image();
    for leaf in leaves.iter().filter(|l| l.number) {
        let allowed = bases
            .iter()
            .find_map(|base| probe(base, &leaf.doc, &image))
            .map_or(Value::Null, Value::String);
        if let Some(Value::Object(p)) = schema.pointer_mut(&leaf.pointer) {
            p.insert("x-allowed".into(), allowed);
        }
    }
    schema
}

/// One key of the configuration, as the reference lists it.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyDoc {
    /// Dotted key (`plant.stage.m2_kg`).
    pub key: String,
    /// `number`, `integer`, `boolean`, `string` or the names allowed (`` `pid` | `ss` ``).
    pub type_text: String,
    /// The default as TOML writes it (None: unset by default, or required in its table).
    pub default: Option<String>,
    /// What a run allows (numbers), as its refusal says it.
    pub allowed: Option<String>,
    /// The doc comment of the key (units stated there).
    pub description: String,
    /// The tagged table and `kind` it belongs to (`scenario`, `sine`), if any.
    pub kind: Option<(String, String)>,
}

/// Every key of `schema` (as [`schema`] made it), depth first.
pub fn key_docs(schema: &Value) -> Vec<KeyDoc> {
    let mut leaves = Vec::new();
    walk(schema, "", "", None, &mut leaves);
    leaves
        .into_iter()
        .map(|l| KeyDoc {
            allowed: schema
                .pointer(&l.pointer)
                .and_then(|p| p.get("x-allowed"))
                .and_then(Value::as_str)
                .map(str::to_owned),
            ..l.doc
        })
        .collect()
}

/// One key and where its schema is.
struct Leaf {
    doc: KeyDoc,
    /// JSON pointer to its schema.
    pointer: String,
    /// Whether it is a number.
    number: bool,
}

/// Every key under the schema at `pointer`, following `$ref`s and the variants of tagged
/// tables.
fn walk(
    root: &Value,
    pointer: &str,
    prefix: &str,
    kind: Option<(String, String)>,
    out: &mut Vec<Leaf>,
) {
    let (pointer, node) = resolve(root, pointer);
    if let Some(props) = node.get("properties").and_then(Value::as_object) {
        for (name, sub) in props {
            let key = if prefix.is_empty() {
                name.clone()
            } else {
                format!("{prefix}.{name}")
            };
            let sub_pointer = format!("{pointer}/properties/{}", name.replace('~', "~0"));
            let (target_pointer, target) = resolve(root, &sub_pointer);
            let items = format!("{target_pointer}/items");
            if is_table(root, target) {
                walk(root, &sub_pointer, &key, kind.clone(), out);
            } else if target.get("type").and_then(Value::as_str) == Some("array")
                && is_table(root, resolve(root, &items).1)
            {
                // An array of tables (`[[plant.modes]]`): its keys as `plant.modes[].hz`.
                walk(root, &items, &format!("{key}[]"), kind.clone(), out);
            } else if target.get("const").is_none() {
                let text = |field: &str| sub.get(field).or_else(|| target.get(field));
                out.push(Leaf {
                    number: is_number(target),
                    pointer: sub_pointer,
                    doc: KeyDoc {
                        type_text: type_text(target),
                        default: text("default").filter(|d| !d.is_null()).map(toml_text),
                        allowed: None,
                        description: text("description")
                            .and_then(Value::as_str)
                            .unwrap_or_default()
                            .to_owned(),
                        key,
                        kind: kind.clone(),
                    },
                });
            }
        }
    }
    if let Some((word, list)) = variants(node) {
        let kinds: Vec<String> = list.iter().filter_map(kind_const).collect();
        if !kinds.is_empty() {
            let names: Vec<String> = kinds.iter().map(|k| format!("`{k}`")).collect();
            out.push(Leaf {
                number: false,
                pointer: pointer.clone(),
                doc: KeyDoc {
                    key: format!("{prefix}.kind"),
                    type_text: names.join(" \\| "),
                    default: None,
                    allowed: None,
                    description: format!("Which `[{prefix}]` this is; its other keys follow."),
                    kind: None,
                },
            });
        }
        for i in 0..list.len() {
            let variant_pointer = format!("{pointer}/{word}/{i}");
            let tag = kind_const(root.pointer(&variant_pointer).unwrap_or(&Value::Null))
                .map(|k| (prefix.to_owned(), k));
            walk(root, &variant_pointer, prefix, tag.or(kind.clone()), out);
        }
    }
}

/// The schema at `pointer` with `$ref` and `Option`'s `anyOf [T, null]` followed.
fn resolve<'a>(root: &'a Value, pointer: &str) -> (String, &'a Value) {
    let mut pointer = pointer.to_owned();
    loop {
        let node = root.pointer(&pointer).unwrap_or(&Value::Null);
        if let Some(r) = node.get("$ref").and_then(Value::as_str) {
            pointer = r.trim_start_matches('#').to_owned();
            continue;
        }
        if let Some(list) = node.get("anyOf").and_then(Value::as_array) {
            let not_null: Vec<usize> = (0..list.len())
                .filter(|&i| list[i].get("type").and_then(Value::as_str) != Some("null"))
                .collect();
            if not_null.len() == 1 && list.len() == 2 {
                pointer = format!("{pointer}/anyOf/{}", not_null[0]);
                continue;
            }
        }
        return (pointer, node);
    }
}

/// The variants of a tagged table (`oneOf` or `anyOf` of objects).
fn variants(node: &Value) -> Option<(&'static str, &Vec<Value>)> {
    ["oneOf", "anyOf"]
        .into_iter()
        .find_map(|w| node.get(w).and_then(Value::as_array).map(|l| (w, l)))
}

/// Whether `node` is a table (properties, or variants that have them), not a value.
fn is_table(root: &Value, node: &Value) -> bool {
    node.get("properties").is_some()
        || variants(node).is_some_and(|(_, list)| {
            list.iter()
                .any(|v| resolve_value(root, v).get("properties").is_some())
        })
}

fn resolve_value<'a>(root: &'a Value, node: &'a Value) -> &'a Value {
    match node.get("$ref").and_then(Value::as_str) {
        Some(r) => root
            .pointer(r.trim_start_matches('#'))
            .unwrap_or(&Value::Null),
        None => node,
    }
}

/// The `kind` a variant of a tagged table is named by.
fn kind_const(node: &Value) -> Option<String> {
    let own = node
        .pointer("/properties/kind/const")
        .and_then(Value::as_str);
    let nested = || {
        node.get("allOf")
            .and_then(Value::as_array)
            .and_then(|l| l.iter().find_map(kind_const))
    };
    own.map(str::to_owned).or_else(nested)
}

/// A value's type as the reference prints it.
fn type_text(node: &Value) -> String {
    let names: Vec<String> = match (node.get("enum"), variants(node)) {
        (Some(Value::Array(e)), _) => e
            .iter()
            .filter_map(Value::as_str)
            .map(str::to_owned)
            .collect(),
        (_, Some((_, list))) => list
            .iter()
            .filter_map(|v| {
                v.get("const")
                    .or_else(|| v.get("enum").and_then(|e| e.get(0)))
            })
            .filter_map(Value::as_str)
            .map(str::to_owned)
            .collect(),
        _ => Vec::new(),
    };
    if !names.is_empty() {
        return names
            .iter()
            .map(|n| format!("`{n}`"))
            .collect::<Vec<_>>()
            .join(" \\| ");
    }
    let types: Vec<&str> = match node.get("type") {
        Some(Value::String(t)) => vec![t.as_str()],
        Some(Value::Array(ts)) => ts.iter().filter_map(Value::as_str).collect(),
        _ => Vec::new(),
    };
    let mut text = types
        .into_iter()
        .filter(|t| *t != "null")
        .collect::<Vec<_>>()
        .join(" or ");
    if text == "array" {
        let of = node.get("items").map(type_text).unwrap_or_default();
        text = format!("array of {of}");
    }
    text
}

/// A JSON default as TOML writes it.
fn toml_text(v: &Value) -> String {
    match v {
        Value::String(s) => format!("{s:?}"),
        other => other.to_string(),
    }
}

fn is_number(node: &Value) -> bool {
    match node.get("type") {
        Some(Value::String(t)) => t == "number",
        Some(Value::Array(ts)) => ts.iter().any(|t| t == "number"),
        _ => false,
    }
}

/// A run with an FIR feedforward (its keys are checked only then; the FRF is not read before
/// they are).
fn fir_feedforward() -> RunConfig {
    let mut c = RunConfig::default();
    c.controller.feedforward = run_config::FeedforwardKind::Fir;
    c.controller.frf_file = Some(crate::plan::FRF_INPUT.into());
    c
}

/// The default run with each scenario kind, machining each preset surface (the image
/// surface's file is [`probe_image`], given to the run as its embedded copy), machining
/// with repetitive control, with the coil current loop, with an extra mode and with an FIR
/// feedforward.
fn base_configs() -> Vec<toml::Value> {
    let image = ImageMap {
        path: SURFACE_INPUT.into(),
        pixel_m: 100e-6,
        depth_range_m: 5e-6,
    };
    ScenarioKind::ALL
        .iter()
        .map(|k| k.scenario(&ScenarioValues::default(), 1.0))
        .chain(SurfacePreset::ALL.iter().map(|p| {
            Scenario::Machine(Machining {
                surface: p.surface(image.clone()),
                ..Machining::default()
            })
        }))
        .map(|scenario| RunConfig {
            scenario,
            ..RunConfig::default()
        })
        .chain(std::iter::once(RunConfig {
            scenario: Scenario::Machine(Machining {
                repetitive: Some(Box::default()),
                ..Machining::default()
            }),
            ..RunConfig::default()
        }))
        .chain(std::iter::once(RunConfig {
            scenario: Scenario::Machine(Machining {
                surface: SurfaceConfig::Prescription {
                    path: PRESCRIPTION_INPUT.into(),
                    nose_compensation: true,
                    clearance_angle_rad: 0.12,
                },
                ..Machining::default()
            }),
            ..RunConfig::default()
        }))
        .chain(std::iter::once(coil_current_loop()))
        .chain(std::iter::once(extra_mode()))
        .chain(std::iter::once(fir_feedforward()))
        .map(|config| toml::Value::try_from(&config).expect("a configuration always serialises"))
        .collect()
}

/// The default run with an extra mode on the reading (its keys are checked only then).
fn extra_mode() -> RunConfig {
    let mut config = RunConfig::default();
    let mode = plant_sim::modes::ExtraMode {
        at: plant_sim::modes::ModeSite::Sensor,
        hz: 1_600.0,
        zeta: 0.01,
        zero_hz: 1_600.0,
        zero_zeta: 0.02,
    };
    config.plant.modes = plant_sim::modes::ExtraModes::new(&[mode]).expect("one mode fits");
    config
}

/// The default run with the R-L coil current loop (its keys are checked only then).
fn coil_current_loop() -> RunConfig {
    let mut config = RunConfig::default();
    config.plant.actuator.model = plant_sim::params::CurrentLoopModel::Coil;
    config
}

/// A 2 × 2 greyscale PNG: the image surface the probes machine.
fn probe_image() -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, 2, 2);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder
        .write_header()
        .expect("a PNG header writes to memory");
    writer
        .write_image_data(&[0, 255, 255, 0])
        .expect("a PNG writes to memory");
    drop(writer);
    bytes
}

/// A prescription as a run embeds it (JSON in SI): 1 µm of Fringe astigmatism over a 40 mm
/// aperture (the default start radius inside it), the surface the prescription probes cut.
fn probe_prescription() -> Vec<u8> {
    let p = optics::Prescription {
        zernike: Some(optics::Zernike {
            order: optics::ZernikeOrder::Fringe,
            norm_radius_m: 0.04,
            coefficients_m: vec![0.0, 0.0, 0.0, 0.0, 1e-6],
        }),
        aperture_radius_m: 0.04,
        ..Default::default()
    };
    serde_json::to_vec(&p).expect("a prescription serialises")
}

/// The range a run's checks name when `leaf` is NaN in `base`, machining `image` if it cuts
/// the image surface (or [`probe_prescription`] if it cuts a prescription) (None: `base` has no such key, or no check refused it).
fn probe(base: &toml::Value, leaf: &KeyDoc, image: &[u8]) -> Option<String> {
    let mut doc = base.clone();
    let (parent, name) = leaf.key.rsplit_once('.').unwrap_or(("", &leaf.key));
    // A key of an array of tables (`plant.modes[].hz`) is probed in the array's first table
    // and refused as `plant.modes[0].hz`.
    let table = parent
        .split('.')
        .filter(|p| !p.is_empty())
        .try_fold(&mut doc, |t, part| match part.strip_suffix("[]") {
            Some(array) => t.get_mut(array)?.get_mut(0),
            None => t.get_mut(part),
        })?
        .as_table_mut()?;
    table.insert(name.to_owned(), toml::Value::Float(f64::NAN));
    // The tagged table may be an ancestor (`scenario` of `scenario.repetitive.…`).
    if let Some((tagged, kind)) = &leaf.kind {
        let at = tagged
            .split('.')
            .try_fold(&doc, |t, part| t.get(part))
            .and_then(|t| t.get("kind"))
            .and_then(toml::Value::as_str);
        if at != Some(kind.as_str()) {
            return None;
        }
    }
    let config: RunConfig = doc.try_into().ok()?;
    let loaded = Loaded {
        config,
        origin: Origin::default(),
    };
    let image = Input {
        name: SURFACE_INPUT.into(),
        media_type: "image/png".into(),
        data: image.to_vec(),
    };
    let prescription = Input {
        name: PRESCRIPTION_INPUT.into(),
        media_type: "application/json".into(),
        data: probe_prescription(),
    };
    match Plan::with_inputs(&loaded, vec![image, prescription]) {
        Err(RunError::Config(ConfigError::Invalid { key, range, .. }))
            if key == leaf.key.replace("[]", "[0]") =>
        {
            Some(range)
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every number of the configuration is checked: set to NaN, a run refuses it and names
    /// its range (a NaN a run accepted would reach the loop).
    #[test]
    fn every_number_has_an_allowed_range() {
        let schema = schema();
        let mut leaves = Vec::new();
        walk(&schema, "", "", None, &mut leaves);
        // What `servo tune` and `servo synth` write about their controller is checked as a
        // whole: a `made_for` that differs from the run's plant or rate is refused naming
        // both, and every run computes its loop's stability again (a carried range that is
        // not a number allows no gain change).
        let provenance = |key: &str| {
            key.starts_with("controller.made_for.") || key.starts_with("controller.stability.")
        };
        let unchecked: Vec<&str> = leaves
            .iter()
            .filter(|l| l.number && !provenance(&l.doc.key))
            .filter(|l| schema.pointer(&l.pointer).unwrap()["x-allowed"].is_null())
            .map(|l| l.doc.key.as_str())
            .collect();
        assert!(unchecked.is_empty(), "no range found for {unchecked:?}");
        let docs = key_docs(&schema);
        let duration = docs.iter().find(|d| d.key == "run.duration_s").unwrap();
        assert_eq!(duration.allowed.as_deref(), Some("(0, 86400] s"));
        assert_eq!(duration.default.as_deref(), Some("1.0"));
        let kind = docs.iter().find(|d| d.key == "controller.kind").unwrap();
        assert_eq!(kind.type_text, "`pid` \\| `accel` \\| `ss`");
    }
}
