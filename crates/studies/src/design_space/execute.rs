//! Running a shard of a study on every local core: workers take the shard's remaining points
//! one at a time, and each finished point goes to the journal at once (so an interruption
//! loses at most the points being evaluated) and to the progress report. The worker pool
//! (`in_parallel`) also runs the sensitivities' loops.

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
    let mut evaluated = 0u64;
    let mut failure = None;
    in_parallel(
        &todo,
        jobs,
        stop,
        |&i| evaluate(study, i),
        |p| match journal.append(&p) {
            Ok(()) => {
                evaluated += 1;
                points.push(p);
                progress(points.len() as u64, total);
                true
            }
            Err(e) => {
                failure = Some(e);
                false
            }
        },
    );
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

/// `work` on each of `items` on `jobs` threads (each takes the next item as it becomes free);
/// `done` gets each result on the calling thread as it comes, in finishing order, and returns
/// whether to go on. Stops taking items once `stop()` is true or `done` said no (items being
/// worked on finish, and their results are dropped after a no).
pub(crate) fn in_parallel<T: Sync, R: Send>(
    items: &[T],
    jobs: usize,
    stop: &(dyn Fn() -> bool + Sync),
    work: impl Fn(&T) -> R + Sync,
    mut done: impl FnMut(R) -> bool,
) {
    let next = AtomicUsize::new(0);
    let cancelled = AtomicBool::new(false);
    let (send, receive) = mpsc::channel::<R>();
    std::thread::scope(|s| {
        for _ in 0..jobs.max(1).min(items.len().max(1)) {
            let send = send.clone();
            let (next, cancelled, work) = (&next, &cancelled, &work);
            s.spawn(move || {
                while !stop() && !cancelled.load(Ordering::Relaxed) {
                    let Some(item) = items.get(next.fetch_add(1, Ordering::Relaxed)) else {
                        break;
                    };
                    if send.send(work(item)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(send);
        for r in receive {
            if !cancelled.load(Ordering::Relaxed) && !done(r) {
                cancelled.store(true, Ordering::Relaxed);
            }
        }
    });
}
