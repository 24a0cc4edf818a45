//! Serving a running loop over iceoryx2 (feature `serve`): a thread of its own publishes the
//! loop's telemetry and health and answers the control plane — gain changes checked against
//! the loop's stability range, controllers loaded (checked, built, handed over bumplessly at a
//! tick boundary), STOP and START for a daemon that closes the loop on its own hardware — so
//! `servo record`, `servo ctl`, `servo view` and the Python tap work against it unchanged.
//!
//! The ticking thread never touches iceoryx2: it exchanges fixed-size messages with the
//! service thread over lock-free single-producer rings (a full telemetry ring drops and counts;
//! nothing blocks the tick).

mod messages;
mod service;

use crate::host::Host;
use crate::load::Vet;
use crate::servo_loop::ServoLoop;
use crate::status::Status;
use daq_io::ipc::IpcError;
use daq_io::{Sensor, Telemetry};
use messages::{Event, Request};
use rtrb::{Consumer, Producer, RingBuffer};
use service::{Service, IDLE};
use servo_config::{Stability, Stage};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

pub(crate) use messages::End;

/// Ticks between two health reports (10 ms at 199.6 kHz).
pub(crate) const SERVICE_TICKS: u64 = 2048;

/// Telemetry records the ring to the service thread holds (0.66 s at 199.6 kHz).
const TELEMETRY_RING: usize = 1 << 17;

/// How a loop is served ([`crate::Servo::serve_with`]).
pub struct ServeOptions {
    /// This process closes the loop on its own hardware (an embedding daemon): it holds the
    /// run's `plant` and `controller` roles, takes STOP and START, and publishes the plant's
    /// records (the command it applied; a daemon knows no simulator truth). False: the
    /// controller process of a HIL run whose plant is another process.
    pub serves_plant: bool,
    /// The check a loaded controller passes (None: the deployment's own rule — the file must
    /// be made for this plant and carry its offline stability check, `[stability]`).
    pub vet: Option<Box<dyn Vet>>,
    /// Wait up to this long for the run's recorder to listen before `serve` returns (0: do not).
    pub wait_for_recorder: Duration,
    /// After the run, how long to wait for subscribers to take the last records.
    pub linger: Duration,
}

impl ServeOptions {
    /// Ticks between two services of the control plane and two health reports (10 ms at
    /// 199.6 kHz): a request is answered within this many ticks.
    pub const SERVICE_TICKS: u64 = SERVICE_TICKS;
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
    /// The ticking thread's ends of the rings, served by `thread` (None: no thread, a test).
    fn new(
        telemetry: Producer<Telemetry>,
        events: Producer<Event>,
        requests: Consumer<Request>,
        thread: Option<JoinHandle<()>>,
    ) -> Self {
        Link {
            telemetry,
            events,
            requests,
            pending: None,
            started: false,
            dropped: 0,
            thread,
        }
    }

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

/// Event slots a health report leaves free: the events that answer a request (a gain change
/// applied, a handover made) always find room, and a report is skipped instead — the next one
/// follows [`SERVICE_TICKS`] later.
const ANSWER_SLOTS: usize = 16;

/// After each tick: telemetry out, requests in, handovers acknowledged, health every
/// [`SERVICE_TICKS`]. An answer is never dropped: a request is taken, and a handover reported,
/// only while the event ring has room for its answer (a stalled service thread delays them).
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
    if let Some((id, radius)) = link.pending.filter(|_| link.events.slots() > 0) {
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
    while link.events.slots() > 0 {
        let Ok(request) = link.requests.pop() else {
            break;
        };
        match request {
            Request::Gain { id, scale } => {
                v.core.set_gain_scale(scale);
                v.status.gain_scale = scale;
                let _ = link.events.push(Event::Gain {
                    id,
                    tick: sample.seq.saturating_add(1),
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
    if sample.seq.is_multiple_of(SERVICE_TICKS) && link.events.slots() > ANSWER_SLOTS {
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
        stop: None,
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
    Ok(Link::new(telemetry, events, requests, Some(thread)))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Deployment;

    /// A link with no service thread behind it: the test holds the far ends of its rings.
    fn link() -> (Link, Consumer<Event>, Producer<Request>) {
        let (telemetry, _) = RingBuffer::new(4);
        let (events, events_rx) = RingBuffer::new(64);
        let (requests_tx, requests) = RingBuffer::new(8);
        (
            Link::new(telemetry, events, requests, None),
            events_rx,
            requests_tx,
        )
    }

    #[test]
    fn a_stalled_service_delays_answers_but_never_loses_them() {
        let d = Deployment::thesis_prototype();
        let mut core = ServoLoop::new(&d).unwrap();
        let host = Host::new(&d);
        let mut status = crate::Servo::new(&d).unwrap().status();
        let mut stability = None;
        let (mut link, mut events, mut requests) = link();
        let mut tick = |link: &mut Link, seq: u64, core: &mut ServoLoop, status: &mut Status| {
            let sample = Sensor {
                seq,
                ..Default::default()
            };
            let v = TickView {
                core,
                status,
                stability: &mut stability,
                telemetry: None,
                host: &host,
            };
            after_tick(link, &sample, v);
        };
        // The service stalls for 200 health periods: reports stop short of the answer slots.
        for seq in 0..200 * SERVICE_TICKS {
            tick(&mut link, seq, &mut core, &mut status);
        }
        assert_eq!(events.slots(), 64 - ANSWER_SLOTS);
        // Gain changes beyond the answer slots: each is applied only once its answer fits.
        let scales: Vec<f64> = (0..20).map(|i| 0.5 + 0.01 * f64::from(i)).collect();
        let mut answered = Vec::new();
        let mut seq = 200 * SERVICE_TICKS;
        for (id, &scale) in scales.iter().enumerate() {
            while requests
                .push(Request::Gain {
                    id: id as u64,
                    scale,
                })
                .is_err()
            {
                tick(&mut link, seq, &mut core, &mut status);
                seq += 1;
                if link.events.slots() == 0 {
                    // The service wakes and takes one event.
                    if let Ok(Event::Gain { id, scale, .. }) = events.pop() {
                        answered.push((id, scale));
                    }
                }
            }
        }
        // Still stalled: what waits in the request ring waits for room.
        assert!(requests.slots() < 8);
        // The service catches up, taking every event after each tick.
        for _ in 0..4 {
            tick(&mut link, seq, &mut core, &mut status);
            seq += 1;
            while let Ok(e) = events.pop() {
                if let Event::Gain { id, scale, .. } = e {
                    answered.push((id, scale));
                }
            }
        }
        let expected: Vec<(u64, f64)> = (0..).zip(scales.iter().copied()).collect();
        assert_eq!(answered, expected);
        assert_eq!(status.gain_scale, *scales.last().unwrap());
    }
}
