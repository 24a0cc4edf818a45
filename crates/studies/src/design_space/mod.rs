//! Design-space studies (thesis §6.5): how the loop's achievable error changes with the
//! structure — moving mass, flexure stiffness and damping, motor constant, any numeric key of
//! the configuration — under a controller family (the H2-optimal controller, H2 tuned to a
//! required bandwidth, or a tuned PID). Each point is a synthesis plus an exact budget.
//!
//! - [`spec`]: the description (a run configuration plus `[study]`);
//! - [`sampling`]: each point's values from its index alone (grid, random, Latin hypercube);
//! - [`evaluate`]: one point — what `servo synth h2` / `servo tune` and `servo budget` give;
//! - [`execute`]: a shard on every local core, journaled as points finish (resumable);
//! - [`journal`]: the study folder, shards and their journals;
//! - [`merge`](gather): shards joined into the table a single run gives;
//! - [`sensitivity`]: elasticities at the operating point;
//! - [`findings`](Findings): what a finished study found; its CSV, Parquet and JSON (the plots
//!   of Fig 6-14 and 6-17 are the `reports` crate's).

pub mod columnar;
pub mod evaluate;
pub mod execute;
mod findings;
pub mod journal;
pub mod sampling;
pub mod sensitivity;
pub mod spec;
pub mod table;

use crate::error::StudyError;
use evaluate::Point;
pub use findings::{axis_label, failures, write_data, Failures, Findings};
use journal::{foreign, io, journals, read_journal, DESCRIPTION};
use serde::Serialize;
use spec::{Family, Objective, Study};
use std::path::{Path, PathBuf};

/// The best point of one family.
#[derive(Debug, Clone, Serialize)]
pub struct Optimum {
    /// Controller family.
    pub controller: Family,
    /// The point's index.
    pub index: u64,
    /// Its parameter values, by key.
    pub values: Vec<(String, f64)>,
    /// Its RMS following error, m.
    pub following_rms_m: f64,
    /// Its RMS true error, m.
    pub true_rms_m: f64,
    /// Its −3 dB bandwidth, Hz.
    pub bandwidth_hz: f64,
}

/// The objective's value of a successful point (NaN for a failed one).
pub fn objective(study: &Study, p: &Point) -> f64 {
    p.outcome
        .as_ref()
        .map_or(f64::NAN, |m| match study.table.objective {
            Objective::Following => m.following_rms_m,
            Objective::True => m.true_rms_m,
        })
}

/// The point of least objective for each family of `study` (families without a successful
/// point have none).
pub fn optima(study: &Study, points: &[Point]) -> Vec<Optimum> {
    study
        .table
        .controllers
        .iter()
        .filter_map(|&family| {
            let best = points
                .iter()
                .filter(|p| p.family == family && p.outcome.is_ok())
                .min_by(|a, b| objective(study, a).total_cmp(&objective(study, b)))?;
            let m = best.outcome.as_ref().ok()?;
            Some(Optimum {
                controller: family,
                index: best.index,
                values: study
                    .table
                    .parameters
                    .iter()
                    .map(|p| p.key.clone())
                    .zip(best.values.iter().copied())
                    .collect(),
                following_rms_m: m.following_rms_m,
                true_rms_m: m.true_rms_m,
                bandwidth_hz: m.bandwidth_hz,
            })
        })
        .collect()
}

/// Every point of the study held in the folders `dirs` (each a study folder with its
/// description and shard journals): the study and its points in index order. Refuses folders
/// of different studies, a point held twice with different results, and a study with points
/// missing (naming the first and its shard).
pub fn gather(dirs: &[PathBuf]) -> Result<(Study, Vec<Point>), StudyError> {
    let mut study: Option<Study> = None;
    let mut points: Vec<Option<Point>> = Vec::new();
    let mut shard_count = 1;
    for dir in dirs {
        let s = Study::from_file(&dir.join(DESCRIPTION))?;
        if let Some(first) = &study {
            if first.sha256 != s.sha256 {
                return Err(foreign(
                    &dir.join(DESCRIPTION),
                    format!(
                        "another study than {} (SHA-256 {} against {})",
                        dirs[0].display(),
                        &s.sha256[..12],
                        &first.sha256[..12]
                    ),
                ));
            }
        } else {
            points = vec![None; s.points() as usize];
            study = Some(s);
        }
        let s = study.as_ref().expect("set above");
        for (path, shard) in journals(dir)? {
            shard_count = shard.count;
            let bytes = daq_io::input_file::read_regular(&path, journal::MAX_JOURNAL_BYTES)
                .map_err(io(&path))?;
            for p in read_journal(s, &path, &bytes, shard)?.0 {
                let slot = &mut points[p.index as usize];
                match slot {
                    Some(held) if *held != p => {
                        return Err(foreign(
                            &path,
                            format!("point {} is held twice with different results", p.index),
                        ))
                    }
                    _ => *slot = Some(p),
                }
            }
        }
    }
    let study = study.ok_or_else(|| foreign(Path::new("."), "no study folders given".into()))?;
    let missing = points.iter().filter(|p| p.is_none()).count();
    if let Some(first) = points.iter().position(Option::is_none) {
        return Err(foreign(
            &dirs[0],
            format!(
                "{missing} of {} points are missing (the first is point {first}, in shard {}/{shard_count}): run the missing shards (or resume them) first",
                points.len(),
                first as u64 % shard_count + 1
            ),
        ));
    }
    Ok((study, points.into_iter().flatten().collect()))
}

/// Finishes a study whose points are all in `points` (index order): computes the sensitivities
/// at the operating point on `jobs` threads (`progress` gets their (done, total) loops) and the
/// findings, and writes the table and summary into `dir` (their plots:
/// `reports::design_space::plots`).
pub fn finish(
    study: &Study,
    points: &[Point],
    dir: &Path,
    jobs: usize,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(Findings, crate::report::Written), StudyError> {
    let sensitivities = sensitivity::sensitivities(study, jobs, progress);
    let findings = Findings::new(study, points, sensitivities);
    let written = write_data(study, points, &findings, dir)?;
    Ok((findings, written))
}
