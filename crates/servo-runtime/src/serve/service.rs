//! The service thread of a served loop: the iceoryx2 ports, telemetry blocks out, health out,
//! the control plane in (gain changes checked against the stability range, controller loads
//! checked and built, STOP and START for a daemon that is the plant).

use super::messages::{End, Event, Request};
use crate::host::Timing;
use crate::load::{self, Refusal, Vet};
use daq_io::contract::{command, role, state};
use daq_io::ipc::{leaf, take, BlockWriter, Endpoint, IpcError, Sender};
use daq_io::{
    ack_status, Ack, Control, ControllerLoad, Health, Telemetry, TelemetryBlock, Truth, TruthBlock,
};
use rtrb::{Consumer, Producer};
use servo_config::Controller;
use servo_config::{Stability, Stage};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How the service thread sleeps when there is nothing to do.
pub(crate) const IDLE: Duration = Duration::from_micros(200);

/// The service thread's state.
pub(crate) struct Service {
    pub(crate) prefix: String,
    pub(crate) serves_plant: bool,
    pub(crate) wait_for_recorder: Duration,
    pub(crate) linger: Duration,
    pub(crate) vet: Box<dyn Vet>,
    pub(crate) stage: Stage,
    pub(crate) period_s: f64,
    pub(crate) stability: Option<Stability>,
    pub(crate) scale: f64,
    /// The CPUs the ticking thread may run on (the service steps aside from them).
    pub(crate) tick_cpus: Vec<usize>,
    /// A STOP the request ring had no room for yet (handed over on a later pass).
    pub(crate) stop: Option<u32>,
}

/// The iceoryx2 side of a service.
struct Ports {
    _roles: Vec<Endpoint>,
    telemetry_pub: daq_io::ipc::Publisher<TelemetryBlock>,
    /// A daemon's plant records (None: the plant is another process).
    truth_pub: Option<daq_io::ipc::Publisher<TruthBlock>>,
    telemetry: BlockWriter<TelemetryBlock>,
    truth: BlockWriter<TruthBlock>,
    control: daq_io::ipc::Subscriber<Control>,
    ack: Sender<Ack>,
    health_pub: Sender<Health>,
    health: Health,
    loads: daq_io::ipc::Subscriber<ControllerLoad>,
    loaded: daq_io::ipc::Publisher<ControllerLoad>,
}

impl Service {
    /// Off the servo path: the ordinary policy, and off the ticking thread's CPUs when it was
    /// pinned and others remain.
    fn step_aside(&self) {
        let online = daq_io::realtime::online_cpus();
        let free: Vec<usize> = (0..online)
            .filter(|c| !self.tick_cpus.contains(c))
            .collect();
        let pinned = !self.tick_cpus.is_empty() && self.tick_cpus.len() < online;
        let _ = daq_io::realtime::apply(&daq_io::realtime::RtSettings {
            cpus: if pinned && !free.is_empty() {
                free
            } else {
                Vec::new()
            },
            ..Default::default()
        });
    }

    fn open(&self) -> Result<Ports, IpcError> {
        let roles: &[&str] = if self.serves_plant {
            &["plant", "controller"]
        } else {
            &["controller-service"]
        };
        let eps = roles
            .iter()
            .map(|r| Endpoint::open(&self.prefix, r))
            .collect::<Result<Vec<_>, _>>()?;
        let ep = &eps[0];
        let telemetry_pub = ep.publisher::<TelemetryBlock>(leaf::TELEMETRY)?;
        let truth_pub = if self.serves_plant {
            Some(ep.publisher::<TruthBlock>(leaf::TRUTH)?)
        } else {
            None
        };
        let ports = Ports {
            telemetry_pub,
            truth_pub,
            telemetry: BlockWriter::new(0),
            truth: BlockWriter::new(0),
            control: ep.subscriber::<Control>(leaf::CONTROL)?,
            ack: Sender::new(ep.publisher::<Ack>(leaf::ACK)?),
            health_pub: Sender::new(ep.publisher::<Health>(leaf::HEALTH)?),
            health: Health {
                role: if self.serves_plant {
                    role::PLANT
                } else {
                    role::CONTROLLER
                },
                state: state::RUNNING,
                ..Default::default()
            },
            loads: ep.subscriber::<ControllerLoad>(leaf::CONTROLLER_LOAD)?,
            loaded: ep.publisher::<ControllerLoad>(leaf::CONTROLLER_LOADED)?,
            _roles: Vec::new(),
        };
        if !self.wait_for_recorder.is_zero() {
            let asked = Instant::now();
            while !daq_io::ipc::recorder_present(ep)? && asked.elapsed() < self.wait_for_recorder {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        Ok(Ports {
            _roles: eps,
            ..ports
        })
    }

    pub(crate) fn run(
        mut self,
        mut telemetry: Consumer<Telemetry>,
        mut events: Consumer<Event>,
        mut requests: Producer<Request>,
        ready: mpsc::SyncSender<Result<(), IpcError>>,
    ) {
        self.step_aside();
        let mut p = match self.open() {
            Ok(p) => p,
            Err(e) => {
                let _ = ready.send(Err(e));
                return;
            }
        };
        daq_io::ipc::connect(&p.telemetry_pub);
        if let Some(t) = &p.truth_pub {
            daq_io::ipc::connect(t);
        }
        p.health_pub.connect();
        p.health_pub.send(p.health);
        p.health_pub.prepare();
        while take(&p.control).is_some() {}
        while let Ok(Some(_)) = p.loads.receive() {}
        let _ = ready.send(Ok(()));
        let start = Instant::now();
        let mut last_tick = 0;
        let mut busy = false;
        let mut started = false;
        loop {
            let mut idle = true;
            // Events first: the run's identity (pushed at the first tick, before any telemetry,
            // so visible whenever telemetry is) names the blocks.
            while let Ok(e) = events.pop() {
                idle = false;
                match e {
                    Event::Started { run_id } => {
                        let id = if run_id != 0 {
                            run_id
                        } else {
                            daq_io::peers::random_id()
                        };
                        p.telemetry = BlockWriter::new(id);
                        p.truth = BlockWriter::new(id);
                        started = true;
                    }
                    Event::Gain { id, tick, scale } => {
                        self.scale = scale;
                        let ack = self.gain_ack(id, tick, scale, ack_status::APPLIED);
                        reply(&mut p, ack);
                    }
                    Event::Loaded {
                        id,
                        tick,
                        radius,
                        replaced,
                    } => {
                        drop(replaced);
                        busy = false;
                        let ack = self.load_ack(id, tick, ack_status::APPLIED, radius);
                        reply(&mut p, ack);
                    }
                    Event::Health {
                        ticks,
                        overruns,
                        timing,
                    } => report(&mut p, start, ticks, overruns, timing),
                    Event::End(End {
                        ticks,
                        overruns,
                        timing,
                        faults,
                        stop_cause,
                    }) => {
                        while let Ok(t) = telemetry.pop() {
                            self.publish(&mut p, t);
                        }
                        // The final report before the end markers: whoever ends on a marker
                        // (the recorder) has it to read.
                        p.health.state = state::ended(faults);
                        p.health.faults = faults;
                        p.health.stop_cause = stop_cause;
                        report(&mut p, start, ticks, overruns, timing);
                        p.telemetry
                            .flush(&p.telemetry_pub, daq_io::flags::END | faults);
                        if let Some(t) = &p.truth_pub {
                            p.truth.flush(t, daq_io::flags::END | faults);
                        }
                        if let Ok(s) = p._roles[0].service::<TelemetryBlock>(leaf::TELEMETRY) {
                            daq_io::ipc::linger(&s, self.linger);
                        }
                        return;
                    }
                }
            }
            if started {
                // What is there now, not until the ring is empty: a loop that fills it as fast
                // as it is published would starve the control plane below.
                for _ in 0..telemetry.slots() {
                    let Ok(t) = telemetry.pop() else { break };
                    idle = false;
                    last_tick = t.seq;
                    self.publish(&mut p, t);
                }
            }
            if let Some(cause) = self.stop {
                if requests.push(Request::Stop { cause }).is_ok() {
                    self.stop = None;
                }
            }
            while let Some(c) = take(&p.control) {
                idle = false;
                self.control(&mut p, &mut requests, &c, last_tick);
            }
            while let Ok(Some(request)) = p.loads.receive() {
                idle = false;
                let (id, file) = (request.id, request.file().to_vec());
                let echo = ControllerLoad::new(id, &file);
                drop(request);
                if let Some(load) = echo {
                    // For the recorder: this process lives as long as the run, the requester
                    // may not.
                    daq_io::ipc::send(&p.loaded, load);
                }
                if busy {
                    let ack = self.load_ack(id, last_tick, ack_status::REFUSED_INVALID, f64::NAN);
                    reply(&mut p, ack);
                    continue;
                }
                match self.prepare(&file) {
                    Ok((controller, stability)) => {
                        let radius = stability.spectral_radius;
                        let sent = requests.push(Request::Load {
                            id,
                            controller,
                            stability,
                            radius,
                        });
                        if sent.is_ok() {
                            busy = true;
                            self.stability = Some(stability);
                        } else {
                            let ack =
                                self.load_ack(id, last_tick, ack_status::REFUSED_INVALID, radius);
                            reply(&mut p, ack);
                        }
                    }
                    Err(r) => {
                        eprintln!("servo: load {id} refused: {r}");
                        let ack = self.load_ack(id, last_tick, r.status, r.spectral_radius);
                        reply(&mut p, ack);
                    }
                }
            }
            if idle {
                std::thread::sleep(IDLE);
            }
        }
    }

    /// Publishes telemetry record `t` (and, for a daemon, the plant's record of the tick: the
    /// command it applied, at the tick's end).
    fn publish(&self, p: &mut Ports, t: Telemetry) {
        p.telemetry.push(&p.telemetry_pub, t);
        if let Some(truth_pub) = &p.truth_pub {
            let truth = Truth {
                seq: t.seq,
                time_s: t.time_s + self.period_s,
                dac_v: t.control_v,
                flags: daq_io::flags::NO_TRUTH,
                ..Default::default()
            };
            p.truth.push(truth_pub, truth);
        }
    }

    /// Checks and builds a loaded controller: refused unless it passes the check and its loop
    /// allows the output scale in force.
    fn prepare(&self, file: &[u8]) -> Result<(Box<Controller>, Stability), Refusal> {
        let v = self.vet.vet(file)?;
        if !v.stability.allows(self.scale) {
            return Err(Refusal {
                status: ack_status::REFUSED_MARGIN,
                spectral_radius: v.stability.spectral_radius,
                message: format!(
                    "stable only for output scales {:.4}..={:.4}; the scale in force is {}",
                    v.stability.low(),
                    v.stability.high(),
                    self.scale
                ),
            });
        }
        let c = load::build(&v, &self.stage, self.period_s)
            .map_err(|e| Refusal::new(ack_status::REFUSED_INVALID, e))?;
        Ok((c, v.stability))
    }

    /// A control message `c` seen after tick `tick`.
    fn control(&mut self, p: &mut Ports, requests: &mut Producer<Request>, c: &Control, tick: u64) {
        let ack = match c.command {
            command::SET_GAIN_SCALE => {
                let status = match self.stability {
                    _ if !c.value.is_finite() => ack_status::REFUSED_INVALID,
                    Some(s) if s.allows(c.value) => {
                        let gain = Request::Gain {
                            id: c.id,
                            scale: c.value,
                        };
                        if requests.push(gain).is_ok() {
                            return; // acknowledged once applied
                        }
                        ack_status::REFUSED_INVALID
                    }
                    _ => ack_status::REFUSED_MARGIN,
                };
                self.gain_ack(c.id, tick, c.value, status)
            }
            command::STOP if self.serves_plant => {
                let cause = daq_io::stop_cause::of_value(c.value);
                if requests.push(Request::Stop { cause }).is_err() {
                    self.stop.get_or_insert(cause);
                }
                Ack::to(c, tick, ack_status::APPLIED, role::PLANT)
            }
            command::START if self.serves_plant => {
                Ack::to(c, tick, ack_status::APPLIED, role::PLANT)
            }
            _ => return, // the plant's
        };
        reply(p, ack);
    }

    /// The answer to gain change `id` to `scale` at `tick`, with the range in force.
    fn gain_ack(&self, id: u64, tick: u64, scale: f64, status: u32) -> Ack {
        let (low, high, unstable_at) = self.stability.map_or((f64::NAN, f64::NAN, f64::NAN), |s| {
            (s.low(), s.high(), s.unstable_above)
        });
        Ack {
            id,
            tick,
            value: scale,
            low,
            high,
            unstable_at,
            command: command::SET_GAIN_SCALE,
            status,
            role: role::CONTROLLER,
            reserved: 0,
        }
    }

    /// The answer to load request `id` at `tick`: `status`, the new loop's spectral radius as
    /// the value, the gain range in force.
    fn load_ack(&self, id: u64, tick: u64, status: u32, spectral_radius: f64) -> Ack {
        Ack {
            command: command::LOAD_CONTROLLER,
            value: spectral_radius,
            ..self.gain_ack(id, tick, spectral_radius, status)
        }
    }
}

fn reply(p: &mut Ports, ack: Ack) {
    p.ack.send(ack);
    p.ack.prepare();
}

fn report(p: &mut Ports, start: Instant, ticks: u64, overruns: u64, timing: Timing) {
    p.health.ticks = ticks;
    p.health.overruns = overruns;
    p.health.wall_s = start.elapsed().as_secs_f64();
    p.health.lateness = timing.lateness;
    p.health.execution = timing.execution;
    p.health_pub.send(p.health);
    p.health_pub.prepare();
}
