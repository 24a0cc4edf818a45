//! One closed-loop run in process: the plan's controller (servo-core) against its simulated
//! stage (plant-sim) through daq-io's in-process transport, recorded to MCAP off the tick,
//! summarised.

use crate::error::RunError;
use crate::pil::{PilError, PilOptions, TargetLoop};
use crate::plan::Plan;
use crate::plan_loop::PlanLoop;
use crate::recording;
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
    on_frame: impl FnMut(&Frame),
) -> Result<Summary, RunError> {
    let radius = plan.check_stable()?;
    run_side(
        plan,
        opts,
        radius,
        Side::Host(PlanLoop::new(plan)?),
        on_frame,
    )
}

/// [`run_with`] with the controller on a target processor (processor in the loop,
/// [`crate::pil`]): the plan's deployment runs in the firmware under QEMU, the stage here.
/// Machining runs are refused (their surface reference is read on the host).
pub fn run_on_target(
    plan: &Plan,
    opts: RunOptions<'_>,
    pil: &PilOptions,
    on_frame: impl FnMut(&Frame),
) -> Result<Summary, RunError> {
    let radius = plan.check_stable()?;
    if plan.surface.is_some() {
        return Err(PilError::Refused(
            "a machining run reads its surface on the host; on the target run the deployment's own references (scenario hold, sine, step, chirp)".into(),
        )
        .into());
    }
    let target = TargetLoop::start(&plan.deployment, pil)?;
    run_side(plan, opts, radius, Side::Target(Box::new(target)), on_frame)
}

/// Where the controller runs.
// One per run, made once: the in-process loop stays inline (no indirection on its tick).
#[allow(clippy::large_enum_variant)]
enum Side {
    /// In this process.
    Host(PlanLoop),
    /// On a target processor.
    Target(Box<TargetLoop>),
}

impl Side {
    fn trip(&self) -> Option<(servo_runtime::TripCause, u64)> {
        match self {
            Side::Host(s) => s.trip(),
            Side::Target(t) => t.trip(),
        }
    }

    fn run_over(&self) -> bool {
        match self {
            Side::Host(s) => s.run_over(),
            Side::Target(t) => t.run_over(),
        }
    }
}

fn run_side(
    plan: &Plan,
    opts: RunOptions<'_>,
    radius: f64,
    mut servo: Side,
    mut on_frame: impl FnMut(&Frame),
) -> Result<Summary, RunError> {
    let c = &plan.config;
    let backend = plan.stage();
    let description = plan.controller.description.clone();
    let on_target = match &servo {
        Side::Target(t) => t.describe(),
        Side::Host(_) => Vec::new(),
    };
    // Progress and stop requests: every 8192 ticks in process (~40 ms), every 64 on a target
    // (a tick there is a round trip through the emulator). A power of two: a mask per tick,
    // not a division.
    let check_mask: u64 = match &servo {
        Side::Target(_) => 64 - 1,
        Side::Host(_) => 8192 - 1,
    };
    let mut recorder = match &opts.out {
        Some(to) => Some(recording::create_with(
            plan,
            to,
            daq_io::peers::random_id(),
            on_target,
        )?),
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
        if s.seq & check_mask == 0 {
            (opts.progress)(s.seq, total);
            if opts.stop.is_set() && s.flags & daq_io::flags::END == 0 {
                reason = opts.stop.reason();
                daq.stop();
                continue;
            }
        }
        let (command, telemetry) = match &mut servo {
            Side::Host(l) => l.tick(&s),
            Side::Target(t) => match t.tick(&s) {
                Ok(answer) => answer,
                Err(e) => {
                    // No command came: the run ends here, the plant left at its last one.
                    t.lose(&e);
                    reason = EndReason::PeerLost;
                    break;
                }
            },
        };
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
    let learned = match &servo {
        Side::Host(l) => l.repetitive_table().map(<[f64]>::to_vec),
        Side::Target(_) => None,
    };
    let target = match servo {
        Side::Target(t) => Some(t.finish()),
        Side::Host(_) => None,
    };
    let stats = match recorder {
        Some(r) => {
            let mut end = recording::end_record(plan, reason, &summary);
            if let Some(t) = &target {
                end.extend(crate::pil::end_facts(t));
            }
            let mut r = r;
            if let (Some(table), Some(p)) = (&learned, &plan.repetitive) {
                end.extend(crate::repetitive::end_facts(p, table));
                r.attach(
                    recorder::Input {
                        name: crate::repetitive::LEARNED_ATTACHMENT.into(),
                        media_type: "text/csv".into(),
                        data: crate::repetitive::table_csv(table).into_bytes(),
                    },
                    (summary.ticks() as f64 * plan.period_s() * 1e9).round() as u64,
                );
            }
            Some(r.finish(end)?)
        }
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
        target,
        repetitive_table_m: learned,
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
