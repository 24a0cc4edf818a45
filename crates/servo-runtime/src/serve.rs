//! Serving a running loop over iceoryx2 (feature `serve`): a thread of its own publishes the
//! loop's telemetry and health and answers the control plane — gain changes checked against
//! the loop's stability range, controllers loaded (checked, built, handed over bumplessly at a
//! tick boundary), STOP and START for a daemon that closes the loop on its own hardware — so
//! `servo record`, `servo ctl`, `servo view` and the Python tap work against it unchanged.
//!
//! The ticking thread never touches iceoryx2: it exchanges fixed-size messages with the
//! service thread over lock-free single-producer rings (a full telemetry ring drops and counts;
//! nothing blocks the tick).

use crate::controller::Controller;
use crate::deployment::{Stability, Stage};
use crate::host::{Host, Timing};
use crate::load::{self, Refusal, Vet};
use crate::servo_loop::ServoLoop;
use crate::status::Status;
use daq_io::contract::{command, role, state};
use daq_io::ipc::{leaf, take, BlockWriter, Endpoint, IpcError, Sender};
use daq_io::{
    ack_status, Ack, Control, ControllerLoad, Health, Sensor, Telemetry, TelemetryBlock, Truth,
    TruthBlock,
};
use rtrb::{Consumer, Producer, RingBuffer};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Ticks between two health reports (10 ms at 199.6 kHz).
pub const SERVICE_TICKS: u64 = 2048;

/// Telemetry records the ring to the service thread holds (0.66 s at 199.6 kHz).
const TELEMETRY_RING: usize = 1 << 17;

/// How the service thread sleeps when there is nothing to do.
const IDLE: Duration = Duration::from_micros(200);

/// How a loop is served ([`crate::Servo::serve_with`]).
pub struct ServeOptions {
    /// This process closes the loop on its own hardware (an embedding daemon): it holds the
    /// run's `plant` and `controller` roles, takes STOP and START, and publishes the plant's
    /// records (the command it applied; a daemon knows no simulator truth). False: the
    /// controller process of a HIL run whose plant is another process.
    pub serves_plant: bool,
    /// The check a loaded controller passes (None: the deployment's own rule,
    /// [`crate::CarriedCheck`]: made for this plant and carrying its offline stability check).
    pub vet: Option<Box<dyn Vet>>,
    /// Wait up to this long for a recorder to subscribe before `serve` returns (0: do not).
    pub wait_for_recorder: Duration,
    /// After the run, how long to wait for subscribers to take the last records.
    pub linger: Duration,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            serves_plant: true,
            vet: None,
            wait_for_recorder: Duration::ZERO,
            linger: Duration::from_secs(5),
        }
    }
}

/// Why a loop could not be served.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    /// The transport refused (the prefix is another live run's, another user's, …).
    #[error(transparent)]
    Transport(#[from] IpcError),
    /// The loop is served already.
    #[error("the loop is served already")]
    AlreadyServed,
    /// The service thread ended unexpectedly.
    #[error("the service thread ended unexpectedly")]
    Lost,
}

/// Service thread → ticking thread.
enum Request {
    Gain {
        id: u64,
        scale: f64,
    },
    Load {
        id: u64,
        controller: Box<Controller>,
        stability: Stability,
        radius: f64,
    },
    Stop {
        cause: u32,
    },
}

/// How a served run ended (the final health report).
pub(crate) struct End {
    pub(crate) ticks: u64,
    pub(crate) overruns: u64,
    pub(crate) timing: Timing,
    pub(crate) faults: u32,
    pub(crate) stop_cause: u32,
}

/// Ticking thread → service thread.
enum Event {
    Started {
        run_id: u64,
    },
    Gain {
        id: u64,
        tick: u64,
        scale: f64,
    },
    Loaded {
        id: u64,
        tick: u64,
        radius: f64,
        replaced: Option<Box<Controller>>,
    },
    Health {
        ticks: u64,
        overruns: u64,
        timing: Timing,
    },
    End(End),
}

/// The ticking thread's end of the rings.
pub(crate) struct Link {
    telemetry: Producer<Telemetry>,
    events: Producer<Event>,
    requests: Consumer<Request>,
    /// A handed-over controller not yet taken up: (request, spectral radius of its loop).
    pending: Option<(u64, f64)>,
    started: bool,
    /// Telemetry records the ring could not take.
    dropped: u64,
    thread: Option<JoinHandle<()>>,
}

impl Link {
    /// Telemetry records dropped so far.
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped
    }
}

/// The parts of a [`crate::Servo`] the exchange after a tick reads and changes.
pub(crate) struct TickView<'a> {
    pub(crate) core: &'a mut ServoLoop,
    pub(crate) status: &'a mut Status,
    pub(crate) stability: &'a mut Option<Stability>,
    pub(crate) telemetry: Option<&'a Telemetry>,
    pub(crate) host: &'a Host,
}

/// After each tick: telemetry out, requests in, handovers acknowledged, health every
/// [`SERVICE_TICKS`].
#[inline]
pub(crate) fn after_tick(link: &mut Link, sample: &Sensor, v: TickView<'_>) {
    if !link.started {
        link.started = true;
        let _ = link.events.push(Event::Started {
            run_id: sample.run_id,
        });
    }
    if let Some(t) = v.telemetry {
        // A full ring drops the record (counted; the recorder sees the gap); the tick never
        // waits.
        if link.telemetry.push(*t).is_err() {
            link.dropped += 1;
        }
    }
    if let Some((id, radius)) = link.pending {
        if let Some(tick) = v.core.handed_over_at() {
            link.pending = None;
            let replaced = v.core.take_replaced();
            let _ = link.events.push(Event::Loaded {
                id,
                tick,
                radius,
                replaced,
            });
        }
    }
    while let Ok(request) = link.requests.pop() {
        match request {
            Request::Gain { id, scale } => {
                v.core.set_gain_scale(scale);
                v.status.gain_scale = scale;
                let _ = link.events.push(Event::Gain {
                    id,
                    tick: sample.seq + 1,
                    scale,
                });
            }
            Request::Load {
                id,
                controller,
                stability,
                radius,
            } => {
                // Only one load is in flight (the service refuses others meanwhile).
                let _ = v.core.hand_over(controller);
                *v.stability = Some(stability);
                link.pending = Some((id, radius));
            }
            Request::Stop { cause } => {
                v.status.stop.get_or_insert(cause);
            }
        }
    }
    if sample.seq.is_multiple_of(SERVICE_TICKS) {
        let _ = link.events.push(Event::Health {
            ticks: v.status.ticks,
            overruns: v.host.overruns(),
            timing: v.host.timing(),
        });
    }
}

/// What the service needs to know of the loop it serves.
pub(crate) struct Setup {
    pub(crate) prefix: String,
    pub(crate) serves_plant: bool,
    pub(crate) wait_for_recorder: Duration,
    pub(crate) linger: Duration,
    pub(crate) vet: Box<dyn Vet>,
    pub(crate) stage: Stage,
    pub(crate) period_s: f64,
    pub(crate) stability: Option<Stability>,
    pub(crate) scale: f64,
}

/// Starts the service thread of `setup`; returns once it is up.
pub(crate) fn start(setup: Setup) -> Result<Link, ServeError> {
    let (telemetry, telemetry_rx) = RingBuffer::new(TELEMETRY_RING);
    let (events, events_rx) = RingBuffer::new(64);
    let (requests_tx, requests) = RingBuffer::new(8);
    let service = Service {
        prefix: setup.prefix,
        serves_plant: setup.serves_plant,
        wait_for_recorder: setup.wait_for_recorder,
        linger: setup.linger,
        vet: setup.vet,
        stage: setup.stage,
        period_s: setup.period_s,
        stability: setup.stability,
        scale: setup.scale,
        tick_cpus: daq_io::realtime::current_cpus(),
    };
    let (ready_tx, ready) = mpsc::sync_channel(1);
    let thread = std::thread::Builder::new()
        .name("servo-service".into())
        .spawn(move || service.run(telemetry_rx, events_rx, requests_tx, ready_tx))
        .map_err(|_| ServeError::Lost)?;
    match ready.recv() {
        Ok(Ok(())) => {}
        Ok(Err(e)) => {
            let _ = thread.join();
            return Err(e.into());
        }
        Err(_) => return Err(ServeError::Lost),
    }
    Ok(Link {
        telemetry,
        events,
        requests,
        pending: None,
        started: false,
        dropped: 0,
        thread: Some(thread),
    })
}

/// Ends the service of `link` with `end` (waiting for the ring to take it), joins its thread;
/// the telemetry records it dropped.
pub(crate) fn close(mut link: Link, end: End) -> u64 {
    let mut end = Some(Event::End(end));
    while let Some(e) = end.take() {
        if let Err(rtrb::PushError::Full(e)) = link.events.push(e) {
            end = Some(e);
            std::thread::sleep(IDLE);
        }
    }
    if let Some(t) = link.thread.take() {
        let _ = t.join();
    }
    link.dropped
}

/// The service thread's state.
struct Service {
    prefix: String,
    serves_plant: bool,
    wait_for_recorder: Duration,
    linger: Duration,
    vet: Box<dyn Vet>,
    stage: Stage,
    period_s: f64,
    stability: Option<Stability>,
    scale: f64,
    tick_cpus: Vec<usize>,
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
            let telemetry = ep.service::<TelemetryBlock>(leaf::TELEMETRY)?;
            let asked = Instant::now();
            while daq_io::ipc::subscriber_count(&telemetry) == 0
                && asked.elapsed() < self.wait_for_recorder
            {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        Ok(Ports {
            _roles: eps,
            ..ports
        })
    }

    fn run(
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
                        p.telemetry
                            .flush(&p.telemetry_pub, daq_io::flags::END | faults);
                        if let Some(t) = &p.truth_pub {
                            p.truth.flush(t, daq_io::flags::END | faults);
                        }
                        p.health.state = state::ended(faults);
                        p.health.faults = faults;
                        p.health.stop_cause = stop_cause;
                        report(&mut p, start, ticks, overruns, timing);
                        if let Ok(s) = p._roles[0].service::<TelemetryBlock>(leaf::TELEMETRY) {
                            daq_io::ipc::linger(&s, self.linger);
                        }
                        return;
                    }
                }
            }
            if started {
                while let Ok(t) = telemetry.pop() {
                    idle = false;
                    last_tick = t.seq;
                    self.publish(&mut p, t);
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
    fn control(&self, p: &mut Ports, requests: &mut Producer<Request>, c: &Control, tick: u64) {
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
                let _ = requests.push(Request::Stop { cause });
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
