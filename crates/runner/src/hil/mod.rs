//! Hardware-in-the-loop: plant, controller and recorder as separate processes over daq-io's
//! iceoryx2 transport. Each function here is the body of one `servo` subcommand.
//!
//! Guarantees: lockstep runs are bit-identical to [`crate::run::run`] with the same config
//! (the same stage, [`Plan::stage`], the same [`PlanLoop`], the same frames); the recorder
//! never blocks the loop (it writes uncompressed MCAP chunks to stay cheap, and has 1024
//! blocks = 65 536 ticks of queue per stream; a full queue overwrites the oldest block and the
//! gap is counted as dropped frames); a lost controller puts the plant in the safe
//! state (see [`daq_io::serve`]); a lost plant stops the controller with [`RunError::PlantLost`].

use crate::error::RunError;
use crate::hot_swap::PlanCheck;
use crate::join::Joiner;
use crate::operator_log::{GainChange, Swap};
use crate::plan::Plan;
use crate::plan_loop::PlanLoop;
use crate::recording;
use crate::stop::{EndReason, StopRequest};
use crate::summary::{HilMeta, RunMeta, Summary, SummaryBuilder};
use daq_io::contract::{command, role};
use daq_io::ipc::{leaf, take, take_waiting, ControlSender, ControllerLink, Endpoint, Tap};
use daq_io::serve::{serve, Pacing, ServeOptions};
use daq_io::{ack_status, flags, Ack, Control, ControllerLoad, Daq, Health};
use recorder::{Frame, Recorder};
use run_config::Role;
use servo_runtime::TripCause;
use std::collections::VecDeque;
use std::time::{Duration, Instant};

mod supervise;
pub use crate::error::ChildFailure;
pub use supervise::{supervise, Supervised, Supervision};

/// Environment variable naming the `servo run --hil` process that started this one (a HIL
/// child follows its parent: it ends when the parent does).
pub const PARENT_ENV: &str = "FTS_SERVO_PARENT";

/// Load requests the recorder remembers while waiting for their acknowledgement.
const MAX_PENDING_LOADS: usize = 16;

/// How long a process waits for its peers to appear.
pub const STARTUP_TIMEOUT: Duration = Duration::from_secs(30);
/// Silence after which the controller declares the plant lost (a loaded 2-core machine can
/// deschedule a process for tens of ms; 1 s is far beyond that).
pub const PLANT_TIMEOUT: Duration = Duration::from_secs(1);

/// The slices a controller waits for its first sample in, checking for a stop between them.
const FIRST_SAMPLE_SLICE: Duration = Duration::from_millis(100);
/// Silence after which the recorder stops waiting for the end of a run.
pub const RECORDER_TIMEOUT: Duration = Duration::from_secs(3);

/// How `servo plant` runs (the rest of [`ServeOptions`] follows from the config).
#[derive(Debug, Clone, Copy)]
pub struct PlantOptions {
    /// Lockstep or real time.
    pub pacing: Pacing,
    /// Wait for the recorder's subscription before the first tick.
    pub wait_for_recorder: bool,
    /// Wait for a control-plane START after the peers are there.
    pub wait_for_start: bool,
    /// Controller silence that counts as lost (default per [`ServeOptions::new`]).
    pub peer_timeout: Option<Duration>,
}

/// The plant server's options for `plan` (`[realtime]` decides the wait, the peer timeout in
/// real time, the grace window and the overrun budget; `p` overrides the peer timeout).
pub fn serve_options(plan: &Plan, p: &PlantOptions) -> ServeOptions {
    let c = &plan.config;
    let rt = &c.realtime;
    let mut opts = ServeOptions::new(c.ticks(), c.plant.period_s(), p.pacing);
    opts.wait_for_recorder = p.wait_for_recorder;
    opts.wait_for_start = p.wait_for_start;
    opts.startup_timeout = STARTUP_TIMEOUT;
    if p.pacing == Pacing::RealTime {
        opts.wait = rt.wait();
        opts.peer_timeout = Duration::from_secs_f64(rt.peer_timeout_s);
        opts.grace = Duration::from_secs_f64(rt.grace_s);
        opts.overrun_rate = rt.overrun_rate;
        opts.overrun_burst_s = rt.overrun_burst_s;
    }
    if let Some(t) = p.peer_timeout {
        opts.peer_timeout = t;
    }
    opts
}

/// `servo plant`: serves the simulated stage of `plan` to the run `prefix` until its duration,
/// a STOP, `stop`, or a fault. Applies `[realtime]`'s plant settings first.
pub fn plant(
    plan: &Plan,
    prefix: &str,
    p: &PlantOptions,
    stop: &StopRequest,
) -> Result<daq_io::serve::ServeReport, RunError> {
    daq_io::realtime::apply(&plan.config.realtime.settings(Role::Plant))?;
    let mut backend = plan.stage();
    let opts = serve_options(plan, p);
    let ep = Endpoint::open(prefix, "plant")?;
    Ok(serve(&ep, &mut backend, &opts, stop.cell())?)
}

/// How a HIL controller's run ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerEnd {
    /// Ticks run.
    pub ticks: u64,
    /// The machine-protection trip (cause, tick), if the loop tripped: it held the safe state
    /// for `protection.after_trip_s`, then asked the plant to end the run.
    pub trip: Option<(TripCause, u64)>,
}

/// `servo controller`: runs the controller of `plan` against the plant of run `prefix` until
/// the plant closes the run. `stop` (Ctrl-C) asks the plant to stop; so does a trip, after the
/// safe state was held. Applies `[realtime]`'s controller settings first. The runtime serves
/// the loop (telemetry, health with each tick's start lateness after the sample's publication
/// and execution time, the control plane with loads checked on the run's model) from a thread
/// of its own, off the servo CPU.
pub fn controller(
    plan: &Plan,
    prefix: &str,
    stop: &StopRequest,
) -> Result<ControllerEnd, RunError> {
    let rt = &plan.config.realtime;
    daq_io::realtime::apply(&rt.settings(Role::Controller))?;
    // The orchestrator checked stability too; a controller never trusts that it did (the
    // gain range refuses an unstable loop).
    let deployment = crate::gain_range::checked(plan)?;
    let mut servo = PlanLoop::with_deployment(plan, &deployment)?;
    let ep = Endpoint::open(prefix, "controller")?;
    // The first sample is waited for in slices, so that a stop ends the wait: a signal, or the
    // supervisor's when the recorder the plant waits for has failed.
    let mut link = ControllerLink::new(&ep, FIRST_SAMPLE_SLICE, PLANT_TIMEOUT)?;
    let waiting = Instant::now();
    let stopper = ControlSender::new(&ep)?;
    servo.servo_mut().serve_with(
        prefix,
        servo_runtime::ServeOptions {
            serves_plant: false,
            vet: Some(Box::new(PlanCheck { plan: plan.clone() })),
            ..servo_runtime::ServeOptions::default()
        },
    )?;
    // With sleep-then-spin the controller sleeps until shortly before the next sample is due.
    let wait = rt.wait();
    let period_ns = (plan.config.plant.period_s() * 1e9).round() as u64;
    let mut stop_sent = false;
    let result = loop {
        let s = match link.read() {
            Ok(s) => s,
            Err(daq_io::DaqError::PlantLost { seq: 0, .. }) if stop.is_set() => break Ok(0),
            Err(daq_io::DaqError::PlantLost { seq: 0, .. })
                if waiting.elapsed() < STARTUP_TIMEOUT =>
            {
                continue
            }
            Err(daq_io::DaqError::PlantLost { seq: 0, .. }) => {
                break Err(RunError::PlantLost(daq_io::DaqError::PlantLost {
                    seq: 0,
                    timeout_ms: STARTUP_TIMEOUT.as_millis() as u64,
                }))
            }
            Err(e) => break Err(RunError::PlantLost(e)),
        };
        let (cmd, _) = servo.tick(&s);
        let Some(cmd) = cmd else {
            break Ok(s.seq);
        };
        if let Err(e) = link.write(cmd) {
            break Err(RunError::PlantLost(e));
        }
        link.prepare();
        if servo.run_over() && !stop_sent {
            stop_sent = stopper.send(stop_for(daq_io::stop_cause::TRIPPED)).is_ok();
        }
        if s.seq
            .is_multiple_of(servo_runtime::ServeOptions::SERVICE_TICKS)
            && stop.is_set()
            && !stop_sent
        {
            let cause = stop.cell().load(std::sync::atomic::Ordering::Relaxed) as u32;
            stop_sent = stopper.send(stop_for(cause)).is_ok();
        }
        if s.published_ns != 0 {
            wait.sleep_before(s.published_ns + period_ns);
        }
    };
    let faults = if result.is_ok() {
        0
    } else {
        flags::FAULT_PEER_LOST
    };
    servo.servo_mut().close(faults);
    result.map(|ticks| ControllerEnd {
        ticks,
        trip: servo.trip(),
    })
}

/// The control-plane STOP that ends a run for `cause` (a [`daq_io::stop_cause`]).
fn stop_for(cause: u32) -> Control {
    Control {
        command: command::STOP,
        value: f64::from(cause),
        ..Default::default()
    }
}

/// `servo record`: records run `prefix` (telemetry joined with truth, tick by tick) to `out`
/// and returns the run's summary, with the plant's overruns, latency and faults. `stop` (a
/// signal to the recorder, as a service manager sends) asks the plant to end the run, with
/// the signal as its cause; the recording is finished as for any end.
pub fn record(
    plan: &Plan,
    prefix: &str,
    out: Option<recording::Target>,
    realtime: bool,
    stop: &StopRequest,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Summary, RunError> {
    let c = &plan.config;
    // Off the servo path: low priority, off the servo CPUs.
    daq_io::realtime::apply(&c.realtime.settings(Role::Other))?;
    let description = plan.controller.description.clone();
    let ep = Endpoint::open(prefix, "recorder")?;
    let tap = Tap::new(&ep)?;
    // Made now: a publisher the plant has not yet seen would lose its first message.
    let stopper = ControlSender::new(&ep)?;
    // What this recorder has taken: a lockstep plant holds while it lags (daq_io::recorder_pace).
    let progress_pub = ep.publisher::<Health>(leaf::RECORDED)?;
    if let Some(to) = &out {
        // Checked now; the file is made when the run's first block names the run.
        to.check()?;
    }
    let mut rec: Option<Recorder> = None;
    let total = c.ticks();
    let mut summary = SummaryBuilder::new(c.run.settle());
    let mut join = Joiner::default();
    let mut plant_health = Health::default();
    let mut controller_health = Health::default();
    let mut last_data: Option<Instant> = None;
    let waiting = Instant::now();
    let mut write_failed = false;
    let mut gain_changes: Vec<GainChange> = Vec::new();
    // Controllers swapped into the loop (`servo ctl load`): each request the controller took
    // up (republished by it), the acknowledgements that it took the loop, paired by id
    // whichever comes first, in order, with the spectral radius it checked.
    let loads = ep.subscriber::<ControllerLoad>(leaf::CONTROLLER_LOADED)?;
    let mut load_requests: VecDeque<(u64, Vec<u8>)> = VecDeque::new();
    let mut applied: VecDeque<Ack> = VecDeque::new();
    let mut swaps: Vec<(Swap, f64)> = Vec::new();
    let mut stop_sent = false;
    loop {
        if stop.is_set() && !stop_sent {
            let cause = stop.cell().load(std::sync::atomic::Ordering::Relaxed) as u32;
            stop_sent = stopper.send(stop_for(cause)).is_ok();
            if last_data.is_none() {
                // Asked to stop before the run began: nothing to record.
                return Err(RunError::Stopped(stop.reason()));
            }
        }
        let mut got = false;
        for b in take_waiting(&tap.telemetry) {
            got = true;
            join.telemetry(&b);
        }
        for b in take_waiting(&tap.truth) {
            got = true;
            join.truth(&b);
        }
        while let Some(h) = take(&tap.health) {
            match h.role {
                role::PLANT => plant_health = h,
                role::CONTROLLER => controller_health = h,
                _ => {}
            }
        }
        while let Ok(Some(l)) = loads.receive() {
            load_requests.push_back((l.id, l.file().to_vec()));
            if load_requests.len() > MAX_PENDING_LOADS {
                load_requests.pop_front();
            }
        }
        while let Some(a) = take(&tap.ack) {
            if a.status != ack_status::APPLIED {
                continue;
            }
            match a.command {
                command::SET_GAIN_SCALE => gain_changes.push(GainChange {
                    tick: a.tick,
                    scale: a.value,
                }),
                command::LOAD_CONTROLLER => {
                    applied.push_back(a);
                    if applied.len() > MAX_PENDING_LOADS {
                        applied.pop_front();
                    }
                }
                _ => {}
            }
        }
        pair_swaps(&mut applied, &mut load_requests, &mut swaps);
        if let (None, Some(id), Some(to)) = (&rec, join.run_id(), &out) {
            rec = Some(recording::create(plan, to, id)?);
        }
        let silent = match last_data {
            Some(t) => !got && t.elapsed() > RECORDER_TIMEOUT,
            None => waiting.elapsed() > STARTUP_TIMEOUT,
        };
        // A lost plant ends the run by silence.
        let finished = join.run_over() || silent;
        join.drain(finished, |f: Frame| {
            summary.add(&f);
            if let Some(r) = &mut rec {
                if r.push(f).is_err() && !write_failed {
                    // The file cannot be written (a full disk): the plant ends the run safely,
                    // as for any stop; the error comes out of finish() below.
                    write_failed = true;
                    let _ = stopper.send(stop_for(daq_io::stop_cause::WRITE_FAILED));
                }
            }
        });
        if got {
            // Before the end check: a short run can arrive whole in one poll.
            last_data = Some(Instant::now());
            progress(join.next_truth(), total);
            let taken = Health {
                role: role::RECORDER,
                state: daq_io::contract::state::RUNNING,
                ticks: join.taken(),
                ..Default::default()
            };
            daq_io::ipc::send(&progress_pub, taken);
        }
        if finished {
            break;
        }
        if !got {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    drop(tap);
    if last_data.is_none() {
        return Err(RunError::NoPeers {
            prefix: prefix.to_owned(),
            waited_s: STARTUP_TIMEOUT.as_secs_f64(),
        });
    }
    let ticks = summary.ticks();
    let plant_faults = join.plant_faults();
    let reason = if plant_faults & flags::FAULT_OVERRUN_BUDGET != 0 {
        EndReason::OverrunBudget
    } else if plant_faults != 0 {
        EndReason::PeerLost
    } else if ticks < total && !join.run_over() {
        // The run ended by silence, without the plant's end marker: the plant was lost
        // (killed or crashed) mid-run.
        EndReason::PeerLost
    } else if ticks < total {
        // The plant's final report says who stopped it (a signal, `servo ctl stop`).
        match EndReason::of_cause(plant_health.stop_cause) {
            EndReason::Completed => EndReason::Stopped,
            reason => reason,
        }
    } else {
        EndReason::Completed
    }
    .after_trip(summary.trip(c.plant.timing.servo_rate_hz).is_some());
    let mut end = recording::end_record(plan, reason, &summary);
    for (i, change) in gain_changes.iter().enumerate() {
        // Every accepted change, with the tick it took effect (`servo ctl gain`).
        change.record(i + 1, &mut end);
    }
    for (i, (swap, radius)) in swaps.iter().enumerate() {
        // Every controller swapped in (`servo ctl load`): its tick, hash and file.
        swap.record(i + 1, plan.period_s(), *radius, &mut end, rec.as_mut());
    }
    let hil = HilMeta {
        realtime,
        overruns: plant_health.overruns,
        latency: plant_health.latency,
        faults: plant_health.faults,
        truth_only_ticks: join.truth_only(),
        plant_lateness: plant_health.lateness,
        plant_execution: plant_health.execution,
        controller_lateness: controller_health.lateness,
        controller_execution: controller_health.execution,
        bad_blocks: join.bad_blocks().count,
        first_bad_block: join.bad_blocks().first.clone(),
    };
    end.extend(hil.record());
    let stats = match rec {
        Some(r) => Some(r.finish(end)?),
        None => None,
    };
    Ok(summary.finish(RunMeta {
        wall_s: Some(plant_health.wall_s),
        interrupted: ticks < total,
        end_reason: Some(reason.name().into()),
        recorded_messages: stats.map(|s| s.messages),
        dropped_frames: Some(join.dropped() + stats.map_or(0, |s| s.dropped_frames)),
        hil: Some(hil),
        ..RunMeta::of(c, description)
    }))
}

/// Moves each applied load acknowledgement whose file has arrived (same request id) to
/// `swaps`, in the order the loop applied them; the others wait for their file.
fn pair_swaps(
    applied: &mut VecDeque<Ack>,
    files: &mut VecDeque<(u64, Vec<u8>)>,
    swaps: &mut Vec<(Swap, f64)>,
) {
    while let Some(a) = applied.front() {
        let Some(at) = files.iter().position(|f| f.0 == a.id) else {
            return;
        };
        let (_, file) = files.remove(at).expect("found above");
        swaps.push((Swap::new(swaps.len() + 1, a.tick, &file), a.value));
        applied.pop_front();
    }
}
