//! Running a shard of a study on every local core: workers take the shard's remaining points
//! one at a time, and each finished point goes to the journal at once (so an interruption
//! loses at most the points being evaluated) and to the progress report.

use super::evaluate::{evaluate, Point};
use super::journal::{claim, pending, Journal, Shard};
use super::spec::Study;
use crate::error::StudyError;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

/// What a shard's run left.
#[derive(Debug)]
pub struct ShardRun {
    /// Every point of the shard finished so far (this run's and earlier runs'), by index.
    pub points: Vec<Point>,
    /// Points this run evaluated.
    pub evaluated: u64,
    /// Points of the shard in all.
    pub total: u64,
}

impl ShardRun {
    /// Whether every point of the shard is done.
    pub fn complete(&self) -> bool {
        self.points.len() as u64 == self.total
    }
}

/// Runs `shard` of `study` in the folder `dir` on `jobs` threads, resuming its journal.
/// `stop()` true ends the run early (points being evaluated finish and are kept); `progress` gets
/// (done, total) points of the shard.
pub fn run_shard(
    study: &Study,
    dir: &Path,
    shard: Shard,
    jobs: usize,
    stop: &(dyn Fn() -> bool + Sync),
    progress: &mut dyn FnMut(u64, u64),
) -> Result<ShardRun, StudyError> {
    claim(study, dir)?;
    let (mut journal, mut points) = Journal::open(study, dir, shard)?;
    let total = shard.points(study.points()).count() as u64;
    let todo = pending(study, shard, &points);
    progress(points.len() as u64, total);
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let (send, receive) = mpsc::channel::<Point>();
    let mut evaluated = 0u64;
    let mut failure = None;
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(todo.len().max(1)) {
            let send = send.clone();
            let (next, todo, failed) = (&next, &todo, &failed);
            s.spawn(move || {
                while !stop() && !failed.load(Ordering::Relaxed) {
                    let Some(&i) = todo.get(next.fetch_add(1, Ordering::Relaxed)) else {
                        break;
                    };
                    if send.send(evaluate(study, i)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(send);
        for p in receive {
            if failure.is_none() {
                match journal.append(&p) {
                    Ok(()) => {
                        evaluated += 1;
                        points.push(p);
                        progress(points.len() as u64, total);
                    }
                    Err(e) => {
                        failed.store(true, Ordering::Relaxed);
                        failure = Some(e);
                    }
                }
            }
        }
    });
    if let Some(e) = failure {
        return Err(e);
    }
    journal.sync()?;
    points.sort_by_key(|p| p.index);
    Ok(ShardRun {
        points,
        evaluated,
        total,
    })
}
