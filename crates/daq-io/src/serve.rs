//! The plant side of a run over iceoryx2: serves a [`Backend`] (the simulator, or a DAQ
//! daemon's hardware) to a controller process, in lockstep or paced to the wall clock.
//!
//! Guarantees:
//! - Lockstep: tick k's command is awaited (busy poll) up to `peer_timeout`; nothing is ever
//!   held or skipped, so a run is bit-identical to the in-process one.
//! - Real time: tick k starts at `t0 + k·T`; a command not in by the start of tick k+1 is an
//!   overrun: the DAC holds its last value (as hardware does) and the count goes up.
//! - Lost controller: no command for `peer_timeout` → the DAC is driven to 0 V (zero current),
//!   [`flags::FAULT_PEER_LOST`] is raised, the plant runs `safe_ticks` more ticks in the safe
//!   state (recorded, so the current's decay is visible) and ends the run.

use crate::contract::{
    ack_status, command, flags, role, state, Ack, Command, Control, Health, Sensor, TruthBlock,
};
use crate::ipc::{leaf, poll_until, take, BlockWriter, Endpoint, IpcError};
use crate::{Backend, LatencyHistogram};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// How ticks are paced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pacing {
    /// As fast as the controller answers; every command awaited.
    Lockstep,
    /// One tick per servo period of wall-clock time; late commands are overruns.
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
    /// Controller silence that counts as lost: lockstep default 200 ms, real time 0.5 ms.
    pub peer_timeout: Duration,
    /// How long to wait for the controller (and recorder) to subscribe.
    pub startup_timeout: Duration,
    /// Also wait for a truth subscriber (the recorder) before the first tick.
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
    /// 0.5 ms (real time; the DAC is at 0 V within 1 ms of the last command), 2 ms of safe state.
    pub fn new(ticks: u64, period_s: f64, pacing: Pacing) -> Self {
        ServeOptions {
            ticks,
            period_s,
            pacing,
            peer_timeout: match pacing {
                Pacing::Lockstep => Duration::from_millis(200),
                Pacing::RealTime => Duration::from_micros(500),
            },
            startup_timeout: Duration::from_secs(30),
            wait_for_recorder: true,
            wait_for_start: false,
            safe_ticks: (2e-3 / period_s).ceil() as u64,
            linger: Duration::from_secs(5),
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
    /// Sticky fault bits ([`flags::FAULT_PEER_LOST`]).
    pub faults: u32,
    /// Tick at which the controller was declared lost.
    pub fault_tick: Option<u64>,
    /// Why it stopped early, a [`crate::stop_cause`] (0: it ran to its end or faulted).
    pub stop_cause: u32,
    /// Round trip sensor → command, plant side.
    pub latency: crate::Latency,
    /// Wall time from the first tick in s.
    pub wall_s: f64,
    /// Truth blocks the transport refused.
    pub truth_refused: u64,
    /// The controller silence that counted as lost.
    pub peer_timeout: Duration,
    /// The run's identity, on every sample and truth block ([`Sensor::run_id`]).
    pub run_id: u64,
}

/// Plant-side errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    /// Transport.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// No controller or recorder subscribed, or no START came, within the startup timeout.
    #[error("no {0} in run {1} within {2:?}: start it with the same --prefix")]
    NoPeer(&'static str, String, Duration),
}

/// Fills the running counts of a health report.
fn progress(health: &mut Health, ticks: u64, report: &ServeReport, t0: Instant) {
    health.ticks = ticks;
    health.overruns = report.overruns;
    health.faults = report.faults;
    health.wall_s = t0.elapsed().as_secs_f64();
}

/// Serves `backend` to the controller of run `ep` until `opts.ticks` commands, a STOP, `stop`
/// (nonzero: a signal number or any request to end), or a lost controller. Health is published every 2048 ticks and at the end.
pub fn serve<B: Backend>(
    ep: &Endpoint,
    backend: &mut B,
    opts: &ServeOptions,
    stop: &AtomicUsize,
) -> Result<ServeReport, ServeError> {
    let sensor_service = ep.service::<Sensor>(leaf::SENSOR)?;
    let truth_service = ep.service::<TruthBlock>(leaf::TRUTH)?;
    let sensor_pub = ep.publisher::<Sensor>(leaf::SENSOR)?;
    let truth_pub = ep.publisher::<TruthBlock>(leaf::TRUTH)?;
    let command_sub = ep.subscriber::<Command>(leaf::COMMAND)?;
    let control_sub = ep.subscriber::<Control>(leaf::CONTROL)?;
    let health_pub = ep.publisher::<Health>(leaf::HEALTH)?;
    let ack_pub = ep.publisher::<Ack>(leaf::ACK)?;
    let ack = |c: &Control, tick: u64| {
        let status = match c.command {
            command::START | command::STOP => ack_status::APPLIED,
            _ => return, // the controller's (gain)
        };
        crate::ipc::send(
            &ack_pub,
            Ack {
                id: c.id,
                tick,
                value: c.value,
                command: c.command,
                status,
                role: role::PLANT,
                ..Default::default()
            },
        );
    };
    let mut health = Health {
        role: role::PLANT,
        state: state::WAITING,
        ..Default::default()
    };

    use iceoryx2::prelude::PortFactory;
    let waiting = Instant::now();
    let mut started = !opts.wait_for_start;
    loop {
        let controller = sensor_service.dynamic_config().number_of_subscribers() > 0;
        let recorder =
            !opts.wait_for_recorder || truth_service.dynamic_config().number_of_subscribers() > 0;
        while let Some(c) = take(&control_sub) {
            started |= c.command == command::START;
            ack(&c, 0);
        }
        if controller && recorder && started {
            break;
        }
        if waiting.elapsed() > opts.startup_timeout || stop.load(Ordering::Relaxed) != 0 {
            let who = match (controller, recorder) {
                (false, _) => "controller",
                (_, false) => "recorder",
                _ => "START (servo ctl start)",
            };
            return Err(ServeError::NoPeer(
                who,
                ep.prefix().into(),
                opts.startup_timeout,
            ));
        }
        crate::ipc::send(&health_pub, health);
        std::thread::sleep(Duration::from_millis(5));
    }

    // Pay every connection set-up now, not inside the timed ticks.
    crate::ipc::connect(&sensor_pub);
    crate::ipc::connect(&truth_pub);
    crate::ipc::connect(&health_pub);
    while take(&control_sub).is_some() {}
    let period = Duration::from_secs_f64(opts.period_s);
    let mut latency = LatencyHistogram::new();
    let run_id = crate::peers::random_id();
    let mut truth = BlockWriter::<TruthBlock>::new(run_id);
    let mut report = ServeReport {
        run_id,
        ..Default::default()
    };
    let mut sample = Sensor {
        seq: 0,
        run_id,
        ..backend.initial()
    };
    let mut dac_v = 0.0;
    let mut last_command = Instant::now();
    let mut end_tick = opts.ticks;
    health.state = state::RUNNING;
    let mut t0 = Instant::now();
    let mut k = 0u64;
    while k < end_tick {
        if k == 1 {
            t0 = Instant::now() - period;
        }
        let tick_start = t0 + period.mul_f64(k as f64);
        if opts.pacing == Pacing::RealTime {
            while Instant::now() < tick_start {
                std::hint::spin_loop();
            }
        }
        crate::ipc::send(&sensor_pub, sample);
        let published = Instant::now();
        let mut tick_flags = 0;
        if report.fault_tick.is_none() {
            // Tick 0 is untimed: its exchange sets up the shared-memory connections (the
            // first receive maps the peer's segment); the wall-clock time base starts after it.
            let deadline = match opts.pacing {
                _ if k == 0 => published + opts.startup_timeout,
                Pacing::Lockstep => published + opts.peer_timeout,
                Pacing::RealTime => tick_start + period,
            };
            match poll_until(&command_sub, deadline, |c| c.seq == k) {
                Some(c) => {
                    last_command = Instant::now();
                    latency.record((last_command - published).as_nanos() as u64);
                    dac_v = c.dac_v;
                }
                None => {
                    report.overruns += (opts.pacing == Pacing::RealTime) as u64;
                    tick_flags |= flags::OVERRUN;
                    // Silence is wall time since the last command: a plant that was itself
                    // descheduled finds the controller's answers waiting and is not fooled.
                    if last_command.elapsed() >= opts.peer_timeout {
                        report.fault_tick = Some(k);
                        report.faults |= flags::FAULT_PEER_LOST;
                        end_tick = k + opts.safe_ticks;
                    }
                }
            }
        }
        if report.fault_tick.is_some() {
            dac_v = 0.0;
        }
        tick_flags |= report.faults;
        let s = backend.step(dac_v);
        sample = Sensor {
            seq: k + 1,
            flags: s.flags | tick_flags,
            run_id,
            ..s
        };
        if let Some(mut t) = backend.truth() {
            t.seq = k;
            t.flags |= tick_flags;
            truth.push(&truth_pub, t);
        }
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
            // The latency percentiles scan the histogram: only in the final report.
            progress(&mut health, k, &report, t0);
            crate::ipc::send(&health_pub, health);
        }
    }
    sample.flags |= flags::END | report.faults;
    crate::ipc::send(&sensor_pub, sample);
    truth.flush(&truth_pub, flags::END | report.faults);
    report.ticks = k;
    report.latency = latency.summary();
    report.wall_s = t0.elapsed().as_secs_f64();
    report.truth_refused = truth.refused();
    report.peer_timeout = opts.peer_timeout;
    health.state = if report.faults != 0 {
        state::FAULTED
    } else {
        state::DONE
    };
    progress(&mut health, k, &report, t0);
    health.latency = report.latency;
    health.stop_cause = report.stop_cause;
    crate::ipc::send(&health_pub, health);
    crate::ipc::linger(&truth_service, opts.linger);
    Ok(report)
}
