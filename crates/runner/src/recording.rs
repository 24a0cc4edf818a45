//! What a run's recording carries (the resolved configuration, version, seed, rate) and
//! reading it back: the configuration a recording was made with, and its summary recomputed.

use crate::config::{ConfigError, Loaded, RunConfig};
use crate::controller::Controller;
use crate::error::RunError;
use crate::summary::{RunMeta, Summary, SummaryBuilder};
use std::collections::BTreeMap;
use std::path::Path;

/// Metadata written into the recording.
pub fn metadata(c: &RunConfig) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("config".to_string(), c.to_toml()),
        ("version".to_string(), env!("CARGO_PKG_VERSION").to_string()),
        ("seed".to_string(), c.run.seed.to_string()),
        (
            "servo_rate_hz".to_string(),
            c.plant.timing.servo_rate_hz.to_string(),
        ),
        ("settle_s".to_string(), c.run.settle().to_string()),
    ])
}

/// A recording written by [`crate::run::run`] and the configuration it was run with.
pub fn read_run(path: &Path) -> Result<(Loaded, recorder::Recording), RunError> {
    let rec = recorder::read(path)?;
    let text = rec
        .metadata
        .get("config")
        .ok_or_else(|| RunError::NotARun(path.to_owned()))?;
    let cfg: RunConfig = toml::from_str(text).map_err(|e| ConfigError::Parse {
        path: path.to_owned(),
        message: e.to_string(),
    })?;
    Ok((
        Loaded {
            config: cfg,
            origin: Default::default(),
        },
        rec,
    ))
}

/// Recomputes the summary of a recording written by [`crate::run::run`].
pub fn inspect(path: &Path) -> Result<Summary, RunError> {
    let (loaded, rec) = read_run(path)?;
    Ok(summarise(&loaded, &rec))
}

/// The summary of the recording `rec` of a run of `loaded`.
pub fn summarise(loaded: &Loaded, rec: &recorder::Recording) -> Summary {
    let cfg = &loaded.config;
    let mut b = SummaryBuilder::new(cfg.run.settle());
    rec.frames.iter().for_each(|f| b.add(f));
    let controller = Controller::build(cfg, &loaded.origin)
        .map(|c| c.description)
        .unwrap_or_else(|_| format!("{:?}", cfg.controller.kind));
    let expected = cfg.ticks();
    b.finish(RunMeta {
        interrupted: (rec.frames.len() as u64) < expected,
        recorded_messages: Some(rec.messages),
        ..RunMeta::of(cfg, controller)
    })
}
