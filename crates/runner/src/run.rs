//! One closed-loop run in process: the plan's controller (servo-core) against its simulated
//! stage (plant-sim) through daq-io's in-process transport, recorded to MCAP off the tick,
//! summarised.

use crate::error::RunError;
use crate::plan::Plan;
use crate::recording;
use crate::servo_loop::ServoLoop;
use crate::sim_backend::SimBackend;
use crate::stop::{EndReason, StopRequest};
use crate::summary::{RunMeta, Summary, SummaryBuilder};
use daq_io::{Backend, Daq, InProcess};
use recorder::Frame;
use std::time::Instant;

/// How to run.
pub struct RunOptions<'a> {
    /// Where to record (None: no recording).
    pub out: Option<recording::Target>,
    /// Set to stop early (a signal, a caller); the run ends at a tick boundary and the
    /// recording is finished with the reason.
    pub stop: &'a StopRequest,
    /// Called every few thousand ticks with (done, total).
    pub progress: &'a mut dyn FnMut(u64, u64),
    /// Compute the loop's digest ([`daq_io::digest::LoopDigest`]) into the summary.
    pub digest: bool,
}

/// Runs `plan`: checks closed-loop stability, runs, records, summarises.
pub fn run(plan: &Plan, opts: RunOptions<'_>) -> Result<Summary, RunError> {
    run_with(plan, opts, |_| {})
}

/// [`run`], showing every recorded frame to `on_frame` as well (analyses that need more than
/// the summary, without reading the file back).
pub fn run_with(
    plan: &Plan,
    opts: RunOptions<'_>,
    mut on_frame: impl FnMut(&Frame),
) -> Result<Summary, RunError> {
    let c = &plan.config;
    let radius = plan.check_stable()?;
    let backend = SimBackend::for_run(plan);
    let mut servo = ServoLoop::new(plan)?;
    let description = plan.controller.description.clone();
    let mut recorder = match &opts.out {
        Some(to) => Some(recording::create(plan, to, daq_io::peers::random_id())?),
        None => None,
    };
    let total = c.ticks();
    let mut summary = SummaryBuilder::new(c.run.settle());
    let start = Instant::now();
    let mut daq = InProcess::new(backend, total);
    let mut reason = EndReason::Completed;
    let mut digest = opts.digest.then(daq_io::digest::LoopDigest::default);
    loop {
        let s = daq.read().expect("in-process reads cannot fail");
        if s.seq.is_multiple_of(8192) {
            (opts.progress)(s.seq, total);
            if opts.stop.is_set() && s.flags & daq_io::flags::END == 0 {
                reason = opts.stop.reason();
                daq.stop();
                continue;
            }
        }
        let (command, telemetry) = servo.tick(&s);
        let Some(command) = command else { break };
        if let Some(d) = &mut digest {
            d.add(&s, &command);
        }
        daq.write(command).expect("in-process writes cannot fail");
        // The tick's telemetry with what the plant did over it.
        let truth = daq.backend().truth().unwrap_or_default();
        if let Some(t) = telemetry {
            let frame = Frame::join(&t, &truth);
            summary.add(&frame);
            on_frame(&frame);
            if let Some(rec) = &mut recorder {
                if rec.push(frame).is_err() {
                    // The writer thread failed (disk full…): the run ends here, safely (no
                    // more commands); the error comes out of finish().
                    reason = EndReason::WriteFailed;
                    break;
                }
            }
        }
        if servo.run_over() && reason == EndReason::Completed {
            // Tripped, and the safe state held long enough: the next sample closes the run.
            reason = EndReason::Tripped;
            daq.stop();
        }
    }
    (opts.progress)(summary.ticks(), total);
    let reason = reason.after_trip(servo.trip().is_some());
    let wall = start.elapsed().as_secs_f64();
    let stats = match recorder {
        Some(r) => Some(r.finish(recording::end_record(plan, reason, &summary))?),
        None => None,
    };
    Ok(summary.finish(RunMeta {
        wall_s: Some(wall),
        interrupted: reason != EndReason::Completed,
        end_reason: Some(reason.name().into()),
        recorded_messages: stats.map(|s| s.messages),
        dropped_frames: stats.map(|s| s.dropped_frames),
        spectral_radius: Some(radius),
        loop_digest: digest.map(|d| format!("{:016x}", d.value())),
        ..RunMeta::of(c, description)
    }))
}

/// [`run`] to the end of `cfg`'s duration: no recording, no progress, no stop flag (sweeps,
/// tests, benches).
pub fn run_to_end(plan: &Plan) -> Result<Summary, RunError> {
    run_to_end_with(plan, |_| {})
}

/// [`run_to_end`], showing every frame to `on_frame` (see [`run_with`]).
pub fn run_to_end_with(plan: &Plan, on_frame: impl FnMut(&Frame)) -> Result<Summary, RunError> {
    let stop = StopRequest::new();
    run_with(
        plan,
        RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
            digest: false,
        },
        on_frame,
    )
}
