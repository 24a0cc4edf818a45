//! iceoryx2 transport: the contract's services under a per-run prefix, zero-copy shared memory,
//! busy polling on the servo path (event wake-ups cost 20–120 µs on a VM; a poll costs ~50 ns).
//!
//! Service names are `fts-servo/<prefix>/<leaf>` with the leaves in [`leaf`]. Every process
//! opens every service with the same settings ([`ServiceSettings`]); opening cleans up the
//! resources of dead nodes first, so a run after a `kill -9` starts cleanly.

use crate::clock::monotonic_ns;
use crate::contract::{
    Ack, Command, Control, Health, RecordBlock, Sensor, TelemetryBlock, TruthBlock,
};
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut_uninit::SampleMutUninit;
use iceoryx2::service::port_factory::publish_subscribe::PortFactory as PubSubFactory;
use std::fmt::Debug;
use std::mem::MaybeUninit;
use std::time::{Duration, Instant};

/// A publisher of `T` on a run service.
pub type Publisher<T> = iceoryx2::port::publisher::Publisher<ipc::Service, T, ()>;
/// A subscriber of `T` on a run service.
pub type Subscriber<T> = iceoryx2::port::subscriber::Subscriber<ipc::Service, T, ()>;
/// A run service carrying `T`.
pub type Service<T> = PubSubFactory<ipc::Service, T, ()>;

/// Transport errors, naming the service and what failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{what}: {detail}")]
pub struct IpcError {
    /// What was being done (`iceoryx2 open service fts-servo/run-1/sensor`, `join run …`).
    pub what: String,
    /// The iceoryx2 error.
    pub detail: String,
}

fn ipc_err(what: impl Into<String>, e: impl Debug) -> IpcError {
    IpcError {
        what: format!("iceoryx2 {}", what.into()),
        detail: format!("{e:?}"),
    }
}

/// Service leaf names.
pub mod leaf {
    /// Plant → controller samples ([`crate::Sensor`]).
    pub const SENSOR: &str = "sensor";
    /// Controller → plant commands ([`crate::Command`]).
    pub const COMMAND: &str = "command";
    /// Controller → recorder ([`crate::TelemetryBlock`]).
    pub const TELEMETRY: &str = "telemetry";
    /// Plant → recorder ([`crate::TruthBlock`]).
    pub const TRUTH: &str = "truth";
    /// Anyone → plant and controller ([`crate::Control`]).
    pub const CONTROL: &str = "control";
    /// Plant and controller → anyone ([`crate::Health`]).
    pub const HEALTH: &str = "health";
    /// Plant and controller → anyone: replies to control messages ([`crate::Ack`]).
    pub const ACK: &str = "ack";
    /// Anyone → controller: a controller to swap in ([`crate::contract::ControllerLoad`]).
    pub const CONTROLLER_LOAD: &str = "controller_load";
    /// Controller → recorder: each load request it took up, republished by the controller
    /// process, which lives as long as the run (the requester may be gone before the recorder
    /// reads its sample, and iceoryx2 takes a departed publisher's samples back); the `Ack`
    /// with the same id says whether and at which tick it took the loop.
    pub const CONTROLLER_LOADED: &str = "controller_loaded";
    /// Recorder → plant: the ticks the recorder has taken ([`crate::Health`] with role
    /// [`crate::contract::role::RECORDER`]); a lockstep plant paces itself on it
    /// ([`crate::recorder_pace`]).
    pub const RECORDED: &str = "recorded";
}

/// Queue sizes and port limits of one service (identical in every process that opens it).
#[derive(Debug, Clone, Copy)]
pub struct ServiceSettings {
    /// Samples a subscriber can hold before the oldest is overwritten (never blocks a sender).
    pub buffer: usize,
    /// Publishers at once.
    pub publishers: usize,
    /// Subscribers at once (recorder, Python taps, …).
    pub subscribers: usize,
}

/// The settings of service `leaf`: on the servo path only the newest sample is kept (one in
/// flight, as iceoryx2's own ping-pong benchmark); 1024 blocks (65 536 ticks, 0.33 s at
/// 199.6 kHz) of room for the recorder.
pub fn settings(leaf: &str) -> ServiceSettings {
    match leaf {
        leaf::TELEMETRY | leaf::TRUTH => ServiceSettings {
            buffer: 1024,
            publishers: 1,
            subscribers: 3,
        },
        leaf::CONTROLLER_LOAD => ServiceSettings {
            buffer: 2,
            publishers: 4,
            subscribers: 3,
        },
        leaf::CONTROLLER_LOADED => ServiceSettings {
            buffer: 16,
            publishers: 1,
            subscribers: 3,
        },
        leaf::CONTROL | leaf::HEALTH | leaf::ACK => ServiceSettings {
            buffer: 64,
            publishers: 4,
            subscribers: 4,
        },
        _ => ServiceSettings {
            buffer: 1,
            publishers: 1,
            subscribers: 2,
        },
    }
}

/// Checks a run prefix: 1–48 characters of `A–Z a–z 0–9 - _`.
pub fn check_prefix(prefix: &str) -> Result<(), String> {
    if prefix.is_empty()
        || prefix.len() > 48
        || !prefix
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        return Err(format!(
            "run prefix {prefix:?}: allowed 1..=48 characters of A-Z a-z 0-9 - _"
        ));
    }
    Ok(())
}

/// One process's attachment to a run: an iceoryx2 node plus the run prefix.
pub struct Endpoint {
    node: Node<ipc::Service>,
    prefix: String,
}

impl Endpoint {
    /// Joins run `prefix` as node `name` (after removing the resources of dead nodes).
    pub fn open(prefix: &str, name: &str) -> Result<Self, IpcError> {
        check_prefix(prefix).map_err(|detail| IpcError {
            what: "run prefix".into(),
            detail,
        })?;
        iceoryx2::prelude::set_log_level(LogLevel::Error);
        let node_name = NodeName::new(&crate::peers::node_name(prefix, name))
            .map_err(|e| ipc_err("node name", e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| {
                ipc_err(
                    "create node (iceoryx2's /tmp/iceoryx2 and /dev/shm/iox2_* are private to the user who made them: is the run another user's?)",
                    e,
                )
            })?;
        node.try_cleanup_dead_nodes();
        // Checked after this node exists: of two processes joining at once, at least one sees
        // the other.
        let peers = crate::peers::live_peers(prefix, Some(node.id()));
        if let Some(detail) = crate::peers::refusal(prefix, name, &peers) {
            return Err(IpcError {
                what: format!("join run {prefix:?} as {name}"),
                detail,
            });
        }
        Ok(Endpoint {
            node,
            prefix: prefix.to_owned(),
        })
    }

    /// The other live processes of this run (see [`crate::peers`]).
    pub fn peers(&self) -> Vec<crate::peers::Peer> {
        crate::peers::live_peers(&self.prefix, Some(self.node.id()))
    }

    /// The run prefix.
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// `fts-servo/<prefix>/<leaf>`.
    pub fn service_name(&self, leaf: &str) -> String {
        format!("fts-servo/{}/{leaf}", self.prefix)
    }

    /// Waits up to `timeout` for a subscriber of service `leaf` carrying `T` to be there — a
    /// message published before any is lost (no history is kept). Whether one is.
    pub fn await_subscriber<T: Debug + ZeroCopySend>(
        &self,
        leaf: &str,
        timeout: Duration,
    ) -> Result<bool, IpcError> {
        let service = self.service::<T>(leaf)?;
        let start = Instant::now();
        while subscriber_count(&service) == 0 {
            if start.elapsed() >= timeout {
                return Ok(false);
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        Ok(true)
    }

    /// Opens (or creates) publish-subscribe service `leaf` carrying `T`.
    pub fn service<T: Debug + ZeroCopySend>(&self, leaf: &str) -> Result<Service<T>, IpcError> {
        let full = self.service_name(leaf);
        let name: ServiceName = full
            .as_str()
            .try_into()
            .map_err(|e| ipc_err(format!("service name {full}"), e))?;
        let s = settings(leaf);
        let mut last = None;
        // Creation races between processes starting together resolve within a few tries.
        for _ in 0..50 {
            match self
                .node
                .service_builder(&name)
                .publish_subscribe::<T>()
                .subscriber_max_buffer_size(s.buffer)
                .history_size(0)
                .enable_safe_overflow(true)
                .max_publishers(s.publishers)
                .max_subscribers(s.subscribers)
                .max_nodes(8)
                .open_or_create()
            {
                Ok(f) => return Ok(f),
                Err(e) => {
                    last = Some(e);
                    std::thread::sleep(Duration::from_millis(2));
                }
            }
        }
        Err(ipc_err(format!("open service {full}"), last))
    }

    /// A publisher on `leaf`.
    pub fn publisher<T: Debug + ZeroCopySend>(&self, leaf: &str) -> Result<Publisher<T>, IpcError> {
        self.service::<T>(leaf)?
            .publisher_builder()
            .create()
            .map_err(|e| ipc_err(format!("publisher on {}", self.service_name(leaf)), e))
    }

    /// A subscriber on `leaf`.
    pub fn subscriber<T: Debug + ZeroCopySend>(
        &self,
        leaf: &str,
    ) -> Result<Subscriber<T>, IpcError> {
        self.service::<T>(leaf)?
            .subscriber_builder()
            .create()
            .map_err(|e| ipc_err(format!("subscriber on {}", self.service_name(leaf)), e))
    }
}

/// The subscribers `service` has now (a controller, a recorder, taps).
pub fn subscriber_count<T: Debug + ZeroCopySend>(service: &Service<T>) -> usize {
    service.dynamic_config().number_of_subscribers()
}

/// Whether run `ep`'s recorder is there and listening: it publishes its progress on the
/// `recorded` leaf only after subscribing to telemetry and truth, so a publisher there means
/// it takes every block from now on (a live view or a tap also subscribes to telemetry and
/// truth, so their subscriber counts do not tell).
pub fn recorder_present(ep: &Endpoint) -> Result<bool, IpcError> {
    let recorded = ep.service::<Health>(leaf::RECORDED)?;
    Ok(recorded.dynamic_config().number_of_publishers() > 0)
}

/// Waits up to `timeout` for the subscribers of `service` to leave (they take the last
/// samples first: samples of a publisher that is gone cannot be received).
pub fn linger<T: Debug + ZeroCopySend>(service: &Service<T>, timeout: Duration) {
    let start = Instant::now();
    while subscriber_count(service) > 0 && start.elapsed() < timeout {
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Sets up `p`'s connections to the subscribers present now, so the first send after it does
/// not pay for it (a sub-millisecond stall a real-time loop would feel).
pub fn connect<T: Debug + ZeroCopySend>(p: &Publisher<T>) {
    use iceoryx2::port::update_connections::UpdateConnections;
    let _ = p.update_connections();
}

/// Sends `value` (copied into a loaned shared-memory sample). Returns false when the
/// transport refused (the caller counts it; the servo path never blocks on it).
#[inline]
pub fn send<T: Debug + ZeroCopySend + Copy>(p: &Publisher<T>, value: T) -> bool {
    p.send_copy(value).is_ok()
}

/// Takes the next sample, if any.
#[inline]
pub fn take<T: Debug + ZeroCopySend + Copy>(s: &Subscriber<T>) -> Option<T> {
    s.receive().ok().flatten().map(|sample| *sample)
}

/// The samples waiting now, at most one buffer of `s` (come back on the next pass for the
/// rest): a reader that drains a publisher as fast as itself until empty never leaves.
pub fn take_waiting<T: Debug + ZeroCopySend + Copy>(
    s: &Subscriber<T>,
) -> impl Iterator<Item = T> + '_ {
    std::iter::from_fn(|| take(s)).take(s.buffer_size())
}

/// A publisher that keeps its next sample loaned: [`Sender::send`] writes and publishes it,
/// and [`Sender::prepare`] loans the next one when the caller is off the exchange's critical
/// path (a loan walks the subscribers' returned samples and allocates its bookkeeping).
pub struct Sender<T: Debug + ZeroCopySend + Copy + 'static> {
    publisher: Publisher<T>,
    next: Option<SampleMutUninit<ipc::Service, MaybeUninit<T>, ()>>,
}

impl<T: Debug + ZeroCopySend + Copy + 'static> Sender<T> {
    /// Wraps `publisher` and loans its first sample.
    pub fn new(publisher: Publisher<T>) -> Self {
        let mut s = Sender {
            publisher,
            next: None,
        };
        s.prepare();
        s
    }

    /// Publishes `value`. Returns false when the transport refused (the caller counts it; the
    /// servo path never blocks on it).
    #[inline]
    pub fn send(&mut self, value: T) -> bool {
        let sample = match self.next.take() {
            Some(s) => s,
            None => match self.publisher.loan_uninit() {
                Ok(s) => s,
                Err(_) => return false,
            },
        };
        sample.write_payload(value).send().is_ok()
    }

    /// Loans the sample of the next send, if not yet loaned.
    #[inline]
    pub fn prepare(&mut self) {
        if self.next.is_none() {
            self.next = self.publisher.loan_uninit().ok();
        }
    }

    /// Sets up connections to the subscribers present now (see [`connect`]).
    pub fn connect(&self) {
        connect(&self.publisher);
    }
}

/// Busy-polls `s` until `accept` takes a sample or the monotonic clock passes `deadline_ns`
/// ([`monotonic_ns`]) and one last look finds none (a waiter descheduled past its deadline
/// still takes what came in time). Returns the sample, still held (returning it to the
/// publisher costs a cross-core cache miss: drop it after the reply is sent). Polls without a
/// pause hint and reads the clock at the first empty poll, then every 64; yields the core after
/// 50 µs of waiting so processes sharing a core still progress.
#[inline]
pub fn poll_held<T: Debug + ZeroCopySend + Copy>(
    s: &Subscriber<T>,
    deadline_ns: u64,
    mut accept: impl FnMut(&T) -> bool,
) -> Option<Sample<ipc::Service, T, ()>> {
    let mut start_ns = 0;
    let mut spins = 0u32;
    let mut past = false;
    loop {
        while let Ok(Some(v)) = s.receive() {
            if accept(&v) {
                return Some(v);
            }
        }
        // The pass after the clock showed the deadline passed was the last look: a waiter
        // descheduled past its deadline has taken what came in time, and does not call its
        // peer silent for its own stall.
        if past {
            return None;
        }
        // The clock is read at the first empty poll (an overdue tick of a plant catching up
        // after a stall returns after one more pass) and then every 64.
        spins = spins.wrapping_add(1);
        if spins % 64 == 1 {
            let now = monotonic_ns();
            past = now >= deadline_ns;
            if start_ns == 0 {
                start_ns = now;
            } else if !past && now - start_ns > 50_000 {
                std::thread::yield_now();
            }
        }
    }
}

/// Accumulates per-tick records into blocks of [`crate::BLOCK_TICKS`] and publishes full
/// blocks, stamped with the run's identity.
pub struct BlockWriter<B> {
    block: B,
    sent: u64,
    refused: u64,
    run_id: u64,
}

impl<B: RecordBlock> BlockWriter<B> {
    /// A writer for the blocks of run `run_id` ([`crate::Sensor::run_id`]).
    pub fn new(run_id: u64) -> Self {
        BlockWriter {
            block: B::default(),
            sent: 0,
            refused: 0,
            run_id,
        }
    }

    /// Adds a record; publishes the block when it is full.
    #[inline]
    pub fn push(&mut self, p: &Publisher<B>, r: B::Record) {
        if self.block.push(r) {
            self.flush(p, 0);
        }
    }

    /// Publishes the block so far with `flags` (e.g. [`crate::flags::END`]; an empty block
    /// is sent only when it carries flags).
    pub fn flush(&mut self, p: &Publisher<B>, flags: u32) {
        if self.block.is_empty() && flags == 0 {
            return;
        }
        self.block.seal(self.sent, flags, self.run_id);
        if !send(p, self.block) {
            self.refused += 1;
        }
        self.sent += 1;
        self.block.clear();
    }

    /// Blocks the transport refused.
    pub fn refused(&self) -> u64 {
        self.refused
    }
}

/// The controller's [`crate::Daq`] over iceoryx2. It keeps to the run of the first sample:
/// a sample with another [`Sensor::run_id`] (another plant on the prefix) is an error. The
/// sample read is held until its command is written (its release is off the round trip), and
/// [`ControllerLink::prepare`] loans the next command's sample after the tick's work.
pub struct ControllerLink {
    sensor: Subscriber<Sensor>,
    command: Sender<Command>,
    held: Option<Sample<ipc::Service, Sensor, ()>>,
    next_seq: u64,
    run_id: u64,
    /// How long to wait for the first sample (the plant may start later), then per sample.
    timeouts: (Duration, Duration),
}

impl ControllerLink {
    /// Subscribes to the sensor service and publishes commands. `first_timeout`: how long
    /// to wait for the plant's first sample; `peer_timeout`: for every later one.
    pub fn new(
        ep: &Endpoint,
        first_timeout: Duration,
        peer_timeout: Duration,
    ) -> Result<Self, IpcError> {
        Ok(ControllerLink {
            sensor: ep.subscriber(leaf::SENSOR)?,
            command: Sender::new(ep.publisher(leaf::COMMAND)?),
            held: None,
            next_seq: 0,
            run_id: 0,
            timeouts: (first_timeout, peer_timeout),
        })
    }

    /// The run of the samples read so far (0 before the first).
    pub fn run_id(&self) -> u64 {
        self.run_id
    }

    /// Loans the next command's sample now, off the exchange (call after the tick's work; a
    /// [`crate::Daq::write`] without it loans at the send).
    pub fn prepare(&mut self) {
        self.command.prepare();
    }
}

impl crate::Daq for ControllerLink {
    #[inline]
    fn read(&mut self) -> Result<Sensor, crate::DaqError> {
        self.held = None;
        let timeout = if self.next_seq == 0 {
            self.timeouts.0
        } else {
            self.timeouts.1
        };
        let want = self.next_seq;
        let deadline = monotonic_ns() + timeout.as_nanos() as u64;
        // The queue keeps only the newest sample: a controller that fell behind (real time)
        // gets the latest, never a stale one.
        match poll_held(&self.sensor, deadline, |s| s.seq >= want) {
            Some(held) => {
                let s = *held;
                self.held = Some(held);
                if want == 0 {
                    self.run_id = s.run_id;
                } else if s.run_id != self.run_id {
                    return Err(crate::DaqError::ForeignRun {
                        expected: self.run_id,
                        got: s.run_id,
                    });
                }
                self.next_seq = s.seq.saturating_add(1);
                Ok(s)
            }
            None => Err(crate::DaqError::PlantLost {
                seq: want,
                timeout_ms: timeout.as_millis() as u64,
            }),
        }
    }

    #[inline]
    fn write(&mut self, command: Command) -> Result<(), crate::DaqError> {
        let sent = self.command.send(command);
        self.held = None;
        if sent {
            Ok(())
        } else {
            Err(crate::DaqError::Transport(
                "command: the transport refused the sample".into(),
            ))
        }
    }
}

/// Everything a process other than plant and controller reads: telemetry, truth, health and
/// the acknowledgements of control-plane changes.
pub struct Tap {
    /// Controller telemetry blocks.
    pub telemetry: Subscriber<TelemetryBlock>,
    /// Plant truth blocks.
    pub truth: Subscriber<TruthBlock>,
    /// Health reports.
    pub health: Subscriber<Health>,
    /// Control-plane acknowledgements.
    pub ack: Subscriber<Ack>,
}

impl Tap {
    /// Subscribes to telemetry, truth, health and acknowledgements of the run.
    pub fn new(ep: &Endpoint) -> Result<Self, IpcError> {
        Ok(Tap {
            telemetry: ep.subscriber(leaf::TELEMETRY)?,
            truth: ep.subscriber(leaf::TRUTH)?,
            health: ep.subscriber(leaf::HEALTH)?,
            ack: ep.subscriber(leaf::ACK)?,
        })
    }
}

/// Sends control-plane messages to a run.
pub struct ControlSender {
    publisher: Publisher<Control>,
}

impl ControlSender {
    /// A control publisher for the run of `ep`.
    pub fn new(ep: &Endpoint) -> Result<Self, IpcError> {
        Ok(ControlSender {
            publisher: ep.publisher(leaf::CONTROL)?,
        })
    }

    /// Sends one message.
    pub fn send(&self, c: Control) -> Result<(), IpcError> {
        self.publisher
            .send_copy(c)
            .map(|_| ())
            .map_err(|e| ipc_err("send control", e))
    }
}
