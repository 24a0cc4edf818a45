//! The plant side of a run over iceoryx2: serves a [`Backend`] (the simulator, or a DAQ
//! daemon's hardware) to a controller process, in lockstep or paced in real time.
//!
//! Guarantees:
//! - Lockstep: tick k's command is awaited (busy poll) up to `peer_timeout`; nothing is ever
//!   held or skipped, so a run is bit-identical to the in-process one. With
//!   [`ServeOptions::wait_for_recorder`] the plant also holds while the recorder lags by half
//!   its queue ([`crate::recorder_pace`]), so the recording loses nothing either.
//! - Real time: tick k starts at its deadline — `t0 + k·T` on the wall clock (waiting by
//!   [`ServeOptions::wait`]), or the backend's own clock edge ([`Backend::wait_for_tick`]), or
//!   at once when the plant is behind; a command not in by the next deadline, or one period
//!   after its sample went out (whichever is later), is an overrun: the DAC holds its last
//!   value (as hardware does) and the count goes up. A plant catching up after a stall of its
//!   own thus keeps the loop closed at the exchange's pace.
//! - Faults ([`crate::watchdog`]): a controller silent for `peer_timeout` (lost), or late more
//!   often than the overrun budget allows, puts the DAC at 0 V (zero current), raises
//!   [`flags::FAULT_PEER_LOST`] or [`flags::FAULT_OVERRUN_BUDGET`], runs `safe_ticks` more
//!   ticks in the safe state (recorded, so the current's decay is visible) and ends the run.
//!   In the startup grace window neither faults the run unless the silence lasts the window.
//! - Statistics: every tick's start lateness, execution time and round trip go into
//!   allocation-free histograms; health reports carry their percentiles.

use crate::clock::{monotonic_ns, Wait};
use crate::contract::{
    ack_status, command, flags, role, state, Ack, Command, Control, Health, Sensor, TruthBlock,
    BLOCK_TICKS,
};
use crate::ipc::{leaf, poll_held, take, BlockWriter, Endpoint, IpcError, Sender};
use crate::recorder_pace::{RecorderPace, PATIENCE};
use crate::watchdog::{FaultPolicy, Verdict, Watchdog};
use crate::{Backend, TickStats};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How ticks are paced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// As fast as the controller answers; every command awaited.
    Lockstep,
    /// One tick per servo period (wall clock, or the backend's clock); late commands are
    /// overruns.
    RealTime,
}

/// What [`serve`] runs.
#[derive(Debug, Clone)]
pub struct ServeOptions {
    /// Ticks (commands) in the run.
    pub ticks: u64,
    /// Servo period in s.
    pub period_s: f64,
    /// Lockstep or real time.
    pub pacing: Pacing,
    /// How a real-time tick waits for its deadline on the wall clock.
    pub wait: Wait,
    /// Controller silence that counts as lost: lockstep default 200 ms, real time 0.5 ms.
    pub peer_timeout: Duration,
    /// Startup grace window (real time): overruns are not charged to the budget and silence
    /// is lost only when it lasts the window. Default 50 ms.
    pub grace: Duration,
    /// The sustained fraction of late ticks the overrun budget absorbs (default 0.05).
    pub overrun_rate: f64,
    /// The overrun budget's burst: overruns beyond the sustained rate at once, in s of ticks
    /// (default 2 ms: the hypervisor stalls of a cloud VM fit).
    pub overrun_burst_s: f64,
    /// How long to wait for the controller (and recorder) to subscribe.
    pub startup_timeout: Duration,
    /// Also wait for the recorder (listening to telemetry and truth) before the first tick.
    pub wait_for_recorder: bool,
    /// After the peers are there, also wait for a control-plane START (`servo ctl start`).
    pub wait_for_start: bool,
    /// Ticks run in the safe state after a fault.
    pub safe_ticks: u64,
    /// After the last tick, how long to wait for truth subscribers to take the final blocks
    /// and leave (samples of a publisher that is gone cannot be received).
    pub linger: Duration,
}

impl ServeOptions {
    /// Defaults for `ticks` at `period_s` with `pacing`: peer timeout 200 ms (lockstep) or
    /// 0.5 ms (real time; the DAC is at 0 V within 1 ms of the last command), 50 ms grace,
    /// overrun budget 5 % sustained with 2 ms bursts, spin waits, 2 ms of safe state.
    pub fn new(ticks: u64, period_s: f64, pacing: Pacing) -> Self {
        ServeOptions {
            ticks,
            period_s,
            pacing,
            wait: Wait::Spin,
            peer_timeout: match pacing {
                Pacing::Lockstep => Duration::from_millis(200),
                Pacing::RealTime => Duration::from_micros(500),
            },
            grace: Duration::from_millis(50),
            overrun_rate: 0.05,
            overrun_burst_s: 2e-3,
            startup_timeout: Duration::from_secs(30),
            wait_for_recorder: true,
            wait_for_start: false,
            safe_ticks: (2e-3 / period_s).ceil() as u64,
            linger: Duration::from_secs(5),
        }
    }

    /// The watchdog's limits (lockstep: only the peer timeout; no budget, no grace).
    pub fn fault_policy(&self) -> FaultPolicy {
        let realtime = self.pacing == Pacing::RealTime;
        FaultPolicy {
            peer_timeout_ns: self.peer_timeout.as_nanos() as u64,
            grace_ns: if realtime {
                self.grace.as_nanos() as u64
            } else {
                0
            },
            overrun_rate: self.overrun_rate,
            overrun_burst: if realtime {
                self.overrun_burst_s / self.period_s
            } else {
                f64::INFINITY
            },
        }
    }
}

/// How a served run went.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ServeReport {
    /// Ticks run (including the safe-state ticks after a fault).
    pub ticks: u64,
    /// Late commands (real time).
    pub overruns: u64,
    /// Of those, in the startup grace window (not charged to the budget).
    pub grace_overruns: u64,
    /// Sticky fault bits ([`flags::FAULT_PEER_LOST`], [`flags::FAULT_OVERRUN_BUDGET`]).
    pub faults: u32,
    /// Tick at which the run was faulted.
    pub fault_tick: Option<u64>,
    /// Why it stopped early, a [`crate::stop_cause`] (0: it ran to its end or faulted).
    pub stop_cause: u32,
    /// Round trip sensor → command, plant side.
    pub latency: crate::Latency,
    /// Start lateness of each tick after its deadline or its backend's clock edge (empty in
    /// lockstep on the wall clock).
    pub lateness: crate::Latency,
    /// The plant's execution time per tick (publish, step, truth; not the wait).
    pub execution: crate::Latency,
    /// Wall time from the first tick in s.
    pub wall_s: f64,
    /// Truth blocks the transport refused.
    pub truth_refused: u64,
    /// The controller silence that counted as lost.
    pub peer_timeout: Duration,
    /// The run's identity, on every sample and truth block ([`Sensor::run_id`]).
    pub run_id: u64,
    /// Lockstep: wall time the plant held for a lagging recorder, s.
    pub recorder_held_s: f64,
    /// Lockstep: at the run's end the recorder had reported no progress for the patience
    /// ([`crate::recorder_pace::PATIENCE`]) and was not waited for.
    pub recorder_silent: bool,
}

/// Plant-side errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    /// Transport.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// No controller or recorder subscribed, or no START came, within the startup timeout.
    #[error("no {0} in run {1} within {2:?}: start it on the same run prefix")]
    NoPeer(&'static str, String, Duration),
    /// Stopped (a signal, or a stop request) while still waiting for a peer.
    #[error("stopped while waiting for the {0} of run {1}")]
    StoppedWaiting(&'static str, String),
}

/// Seconds of monotonic time since `start_ns`.
fn seconds_since(start_ns: u64) -> f64 {
    monotonic_ns().saturating_sub(start_ns) as f64 * 1e-9
}

/// Fills the running counts of a health report; `start_ns` is when tick 1 was due.
fn progress(
    health: &mut Health,
    ticks: u64,
    report: &ServeReport,
    stats: &TickStats,
    start_ns: u64,
) {
    health.ticks = ticks;
    health.overruns = report.overruns;
    health.faults = report.faults;
    health.wall_s = seconds_since(start_ns);
    stats.report(health);
}

/// Waits until the controller (and the recorder, and a START if asked) are there.
fn wait_for_peers(
    ep: &Endpoint,
    opts: &ServeOptions,
    stop: &AtomicUsize,
    control_sub: &crate::ipc::Subscriber<Control>,
    health_pub: &mut Sender<Health>,
    ack: &mut impl FnMut(&Control, u64),
) -> Result<(), ServeError> {
    use crate::ipc::subscriber_count;
    let sensor_service = ep.service::<Sensor>(leaf::SENSOR)?;
    let health = Health {
        role: role::PLANT,
        state: state::WAITING,
        ..Default::default()
    };
    let waiting = Instant::now();
    let mut started = !opts.wait_for_start;
    loop {
        let controller = subscriber_count(&sensor_service) > 0;
        let recorder = !opts.wait_for_recorder || crate::ipc::recorder_present(ep)?;
        while let Some(c) = take(control_sub) {
            started |= c.command == command::START;
            ack(&c, 0);
        }
        if controller && recorder && started {
            return Ok(());
        }
        if waiting.elapsed() > opts.startup_timeout || stop.load(Ordering::Relaxed) != 0 {
            let who = match (controller, recorder) {
                (false, _) => "controller",
                (_, false) => "recorder",
                _ => "START (servo ctl start)",
            };
            return Err(if stop.load(Ordering::Relaxed) != 0 {
                ServeError::StoppedWaiting(who, ep.prefix().into())
            } else {
                ServeError::NoPeer(who, ep.prefix().into(), opts.startup_timeout)
            });
        }
        health_pub.send(health);
        health_pub.prepare();
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Serves `backend` to the controller of run `ep` until `opts.ticks` commands, a STOP, `stop`
/// (nonzero: a signal number or any request to end), or a fault. Health is published every
/// 2048 ticks and at the end.
pub fn serve<B: Backend>(
    ep: &Endpoint,
    backend: &mut B,
    opts: &ServeOptions,
    stop: &AtomicUsize,
) -> Result<ServeReport, ServeError> {
    let truth_service = ep.service::<TruthBlock>(leaf::TRUTH)?;
    let mut sensor_pub = Sender::new(ep.publisher::<Sensor>(leaf::SENSOR)?);
    let truth_pub = ep.publisher::<TruthBlock>(leaf::TRUTH)?;
    let command_sub = ep.subscriber::<Command>(leaf::COMMAND)?;
    let control_sub = ep.subscriber::<Control>(leaf::CONTROL)?;
    let mut health_pub = Sender::new(ep.publisher::<Health>(leaf::HEALTH)?);
    let mut ack_pub = Sender::new(ep.publisher::<Ack>(leaf::ACK)?);
    let mut ack = |c: &Control, tick: u64| {
        let status = match c.command {
            command::START | command::STOP => ack_status::APPLIED,
            _ => return, // the controller's (gain)
        };
        ack_pub.send(Ack::to(c, tick, status, role::PLANT));
        ack_pub.prepare();
    };
    let mut pace = match opts.pacing {
        Pacing::Lockstep if opts.wait_for_recorder => Some(RecorderPace::new(ep, PATIENCE)?),
        _ => None,
    };
    wait_for_peers(ep, opts, stop, &control_sub, &mut health_pub, &mut ack)?;

    // Pay every connection set-up now, not inside the timed ticks.
    sensor_pub.connect();
    crate::ipc::connect(&truth_pub);
    health_pub.connect();
    while take(&control_sub).is_some() {}
    let period_ns = (opts.period_s * 1e9).round() as u64;
    let realtime = opts.pacing == Pacing::RealTime;
    let mut stats = TickStats::default();
    let mut watchdog = Watchdog::new(opts.fault_policy());
    let run_id = crate::peers::random_id();
    let mut truth = BlockWriter::<TruthBlock>::new(run_id);
    let mut report = ServeReport {
        run_id,
        ..Default::default()
    };
    let mut health = Health {
        role: role::PLANT,
        state: state::RUNNING,
        ..Default::default()
    };
    let mut sample = Sensor {
        seq: 0,
        run_id,
        time_s: 0.0,
        ..backend.initial()
    };
    // Run time: the backend's clock rebased so that the first command's reading is at one
    // period (a daemon's stage keeps its clock from session to session; recordings, settle
    // times and windows count from 0). The simulator's clock starts there: rebased by 0.
    let mut clock_zero_s = None;
    let mut dac_v = 0.0;
    let mut end_tick = opts.ticks;
    // The wall-clock time base: tick k's deadline is base + k·T (reset after tick 0).
    let mut base_ns = monotonic_ns().saturating_sub(period_ns);
    let mut k = 0u64;
    while k < end_tick {
        if k == 1 {
            base_ns = monotonic_ns() - period_ns;
        }
        // The tick's deadline and when it really started.
        let mut clocked = realtime;
        let (deadline_ns, start_ns) = match backend.wait_for_tick(k) {
            Some(edge_ns) => {
                clocked = true;
                (edge_ns, monotonic_ns())
            }
            None if realtime && k > 0 => {
                let deadline = base_ns + k * period_ns;
                (deadline, opts.wait.until(deadline))
            }
            None => {
                let now = monotonic_ns();
                (now, now)
            }
        };
        if k > 0 && clocked {
            stats.lateness.record(start_ns.saturating_sub(deadline_ns));
        }
        sample.published_ns = monotonic_ns();
        sensor_pub.send(sample);
        let published_ns = sample.published_ns;
        let mut tick_flags = 0;
        let mut answered_ns = published_ns;
        if report.fault_tick.is_none() {
            // Tick 0 is untimed: its exchange sets up the shared-memory connections (the
            // first receive maps the peer's segment); the time base starts after it.
            let command_deadline = match opts.pacing {
                _ if k == 0 => published_ns + opts.startup_timeout.as_nanos() as u64,
                Pacing::Lockstep => published_ns + opts.peer_timeout.as_nanos() as u64,
                // The controller has one period from the sample's publication: a plant that
                // catches up after a stall of its own keeps the loop closed (the controller
                // sees every sample in order) and catches up at the exchange's pace.
                Pacing::RealTime => (deadline_ns + period_ns).max(published_ns + period_ns),
            };
            let mut heard = false;
            let got = poll_held(&command_sub, command_deadline, |c| {
                heard = true;
                c.seq == k
            });
            answered_ns = monotonic_ns();
            let late = got.is_none();
            if let Some(c) = got {
                stats.round_trip.record(answered_ns - published_ns);
                dac_v = c.dac_v;
            } else {
                report.overruns += realtime as u64;
                tick_flags |= flags::OVERRUN;
            }
            let verdict = if k == 0 {
                if late {
                    Verdict::PeerLost
                } else {
                    Verdict::Ok
                }
            } else {
                let rel = |t: u64| t.saturating_sub(base_ns);
                watchdog.tick(rel(answered_ns), rel(published_ns), late, heard)
            };
            let fault = match verdict {
                Verdict::Ok => 0,
                Verdict::PeerLost => flags::FAULT_PEER_LOST,
                Verdict::OverrunBudget => flags::FAULT_OVERRUN_BUDGET,
            };
            if fault != 0 {
                report.fault_tick = Some(k);
                report.faults |= fault;
                end_tick = k + opts.safe_ticks;
            }
        }
        if report.fault_tick.is_some() {
            dac_v = 0.0;
        }
        tick_flags |= report.faults;
        let s = backend.step(dac_v);
        let zero = *clock_zero_s.get_or_insert(s.time_s - opts.period_s);
        sample = Sensor {
            seq: k + 1,
            time_s: s.time_s - zero,
            flags: s.flags | tick_flags,
            run_id,
            ..s
        };
        if let Some(mut t) = backend.truth() {
            t.seq = k;
            t.time_s -= zero;
            t.flags |= tick_flags;
            truth.push(&truth_pub, t);
        }
        if k > 0 {
            let own = (published_ns - start_ns) + (monotonic_ns() - answered_ns);
            stats.execution.record(own);
        }
        if let Some(p) = pace
            .as_mut()
            .filter(|_| k.is_multiple_of(BLOCK_TICKS as u64))
        {
            p.hold(k, || {
                let held = Health {
                    state: state::HELD_FOR_RECORDER,
                    ticks: k,
                    ..health
                };
                health_pub.send(held);
                health_pub.prepare();
            });
        }
        sensor_pub.prepare();
        k += 1;
        if k.is_multiple_of(2048) {
            while let Some(c) = take(&control_sub) {
                if c.command == command::STOP && report.stop_cause == 0 {
                    end_tick = end_tick.min(k);
                    report.stop_cause = crate::stop_cause::of_value(c.value);
                }
                ack(&c, k);
            }
            let asked = stop.load(Ordering::Relaxed);
            if asked != 0 && report.stop_cause == 0 {
                end_tick = end_tick.min(k);
                report.stop_cause = u32::try_from(asked).unwrap_or(crate::stop_cause::CONTROL);
            }
            progress(&mut health, k, &report, &stats, base_ns + period_ns);
            health_pub.send(health);
            health_pub.prepare();
        }
    }
    // The final report before the end markers: whoever ends on a marker (the recorder, taking
    // its end reason and statistics from this report) has it to read.
    health.state = state::ended(report.faults);
    progress(&mut health, k, &report, &stats, base_ns + period_ns);
    health.stop_cause = report.stop_cause;
    health_pub.send(health);
    sample.flags |= flags::END | report.faults;
    sensor_pub.send(sample);
    truth.flush(&truth_pub, flags::END | report.faults);
    report.ticks = k;
    report.grace_overruns = watchdog.grace_overruns();
    report.latency = stats.round_trip.summary();
    report.lateness = stats.lateness.summary();
    report.execution = stats.execution.summary();
    report.wall_s = seconds_since(base_ns + period_ns);
    report.truth_refused = truth.refused();
    report.peer_timeout = opts.peer_timeout;
    if let Some(p) = &pace {
        report.recorder_held_s = p.held_s();
        report.recorder_silent = p.silent();
    }
    crate::ipc::linger(&truth_service, opts.linger);
    Ok(report)
}
