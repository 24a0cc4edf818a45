//! A run configuration from Python: a TOML file (path), a dict, or nothing (the thesis
//! defaults), with a dict of overrides merged table by table on top.

use crate::servo_err;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};
use run_config::{ConfigError, Loaded, Origin, RunConfig};
use std::path::PathBuf;
use toml::{Table, Value};

/// A Python value as TOML (bool, int, float, str, list/tuple, dict with str keys).
fn to_toml(v: &Bound<'_, PyAny>, key: &str) -> PyResult<Value> {
    if v.is_instance_of::<PyBool>() {
        Ok(Value::Boolean(v.extract()?))
    } else if v.is_instance_of::<PyInt>() {
        Ok(Value::Integer(v.extract()?))
    } else if v.is_instance_of::<PyFloat>() {
        Ok(Value::Float(v.extract()?))
    } else if v.is_instance_of::<PyString>() {
        Ok(Value::String(v.extract()?))
    } else if let Ok(d) = v.cast::<PyDict>() {
        Ok(Value::Table(table_of(d, key)?))
    } else if v.is_instance_of::<PyList>() || v.is_instance_of::<PyTuple>() {
        let mut items = Vec::new();
        for (i, item) in v.try_iter()?.enumerate() {
            items.push(to_toml(&item?, &format!("{key}[{i}]"))?);
        }
        Ok(Value::Array(items))
    } else {
        Err(servo_err(format!(
            "configuration key {key}: a {} is not a TOML value (bool, int, float, str, list, dict)",
            v.get_type().name()?
        )))
    }
}

/// A dict as a TOML table; keys must be strings.
fn table_of(d: &Bound<'_, PyDict>, prefix: &str) -> PyResult<Table> {
    let mut t = Table::new();
    for (k, v) in d.iter() {
        let k: String = k
            .extract()
            .map_err(|_| servo_err(format!("configuration table {prefix:?}: keys are str")))?;
        let key = if prefix.is_empty() {
            k.clone()
        } else {
            format!("{prefix}.{k}")
        };
        t.insert(k, to_toml(&v, &key)?);
    }
    Ok(t)
}

/// `over` merged into `base`: tables key by key, anything else replaced.
fn merge(base: &mut Table, over: Table) {
    for (k, v) in over {
        match (base.get_mut(&k), v) {
            (Some(Value::Table(b)), Value::Table(o)) => merge(b, o),
            (_, v) => {
                base.insert(k, v);
            }
        }
    }
}

/// The configuration `config` (None, a path, or a dict) with `overrides` on top, located at
/// the file it came from.
pub fn load(
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<Loaded> {
    let (mut table, origin) = match config {
        None => (Table::new(), Origin::default()),
        Some(c) if c.is_instance_of::<PyDict>() => {
            (table_of(c.cast::<PyDict>()?, "")?, Origin::default())
        }
        Some(c) => {
            let path: PathBuf = c.extract().map_err(|_| {
                servo_err("config: a path to a TOML file, a dict, or None (the thesis defaults)")
            })?;
            let text = run_config::input_file::read_text(&path).map_err(servo_err)?;
            let table = toml::from_str::<Table>(&text).map_err(|e| {
                servo_err(ConfigError::Parse {
                    path: path.clone(),
                    message: e.to_string(),
                })
            })?;
            (
                table,
                Origin {
                    path: Some(path),
                    text: Some(text),
                },
            )
        }
    };
    if let Some(o) = overrides {
        merge(&mut table, table_of(o, "")?);
    }
    let config: RunConfig = Value::Table(table)
        .try_into()
        .map_err(|e: toml::de::Error| {
            servo_err(ConfigError::Parse {
                path: origin
                    .path
                    .clone()
                    .unwrap_or_else(|| PathBuf::from("<dict>")),
                message: e.to_string(),
            })
        })?;
    Ok(Loaded { config, origin })
}

/// The plan of `config` with `overrides` (validated, built; errors located).
pub fn plan(
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<runner::Plan> {
    built(&load(config, overrides)?)
}

/// The plan of `loaded` (validated, built; errors located).
pub fn built(loaded: &Loaded) -> PyResult<runner::Plan> {
    runner::Plan::new(loaded).map_err(servo_err)
}

/// The resolved configuration (every default filled in) as TOML text.
#[pyfunction]
#[pyo3(signature = (config=None, overrides=None))]
pub fn resolved_config(
    config: Option<&Bound<'_, PyAny>>,
    overrides: Option<&Bound<'_, PyDict>>,
) -> PyResult<String> {
    Ok(plan(config, overrides)?.config.to_toml())
}
