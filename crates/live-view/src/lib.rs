//! # live-view
//!
//! A live view of a running HIL run in Foxglove: `servo view --prefix P` taps the run's
//! telemetry and truth over shared memory the way the recorder does (its own process: the
//! servo path never waits for it; a slow view loses its own samples, counted), joins them tick
//! by tick, and serves the Foxglove WebSocket protocol ([`ws`]: on loopback to the run's own
//! Unix user only; beyond loopback only with a token, over TLS unless cleartext is asked for;
//! read-only if asked):
//! - `/overview`: per millisecond of run, the minimum, maximum and mean of the main signals —
//!   the recording's own `/overview` bins, so what a browser shows is what the file holds;
//!   `every` publishes only each n-th bin;
//! - `/health`: the plant's and controller's reports (ticks, overruns, latency);
//! - parameters: `gain_scale` (settable: sent as `servo ctl gain`, applied only if the loop
//!   keeps its margin, the value the run acknowledged) and read-only `run.*` metadata;
//! - service `stop`: ends the run as `servo ctl stop` does.

mod messages;
mod operator;
pub mod ws;

pub use operator::{GAIN_SCALE, STOP_SERVICE};

use daq_io::ipc::{take, take_waiting, Endpoint, IpcError, Tap};
use operator::Operator;
use recorder::OverviewBin;
use runner::join::Joiner;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use ws::protocol::Parameter;
use ws::{Channel, Front, FrontOptions, Service};

/// What [`serve`] serves and where.
#[derive(Debug, Clone)]
pub struct ViewOptions {
    /// Run prefix.
    pub prefix: String,
    /// Address to bind (default 127.0.0.1).
    pub host: String,
    /// TCP port (0: any free one; the listener hears which).
    pub port: u16,
    /// Publish every n-th overview bin (1: every millisecond of run).
    pub every: u32,
    /// How long to wait for the run to start, s.
    pub startup_timeout: Duration,
    /// How long to keep serving after the run ended (clients take the last messages).
    pub linger: Duration,
    /// Offer no parameters and no services (watch only).
    pub read_only: bool,
    /// A token every client must present (`?token=…`); required when `host` is not a
    /// loopback address.
    pub token: Option<String>,
    /// Serve TLS (`wss://`) with this identity; required when `host` is not a loopback
    /// address, unless `cleartext`.
    pub tls: Option<ws::tls::Tls>,
    /// Serve beyond loopback without TLS (the token and the data in cleartext: on a network
    /// every machine on the path is trusted, or through a tunnel).
    pub cleartext: bool,
}

impl ViewOptions {
    /// Localhost on `port`, every bin, 30 s for the run to start, 1 s of linger.
    pub fn new(prefix: &str, port: u16) -> Self {
        ViewOptions {
            prefix: prefix.to_owned(),
            host: "127.0.0.1".into(),
            port,
            every: 1,
            startup_timeout: Duration::from_secs(30),
            linger: Duration::from_secs(1),
            read_only: false,
            token: None,
            tls: None,
            cleartext: false,
        }
    }
}

/// How a view ended.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ViewReport {
    /// Overview samples published.
    pub overview_samples: u64,
    /// Ticks seen.
    pub ticks: u64,
    /// Records the view lost (it fell behind; the run did not).
    pub dropped: u64,
    /// Gain scales the run applied at this view's request.
    pub applied_gains: Vec<f64>,
    /// Whether the run ended (rather than the view being stopped or timing out).
    pub run_ended: bool,
    /// Connections refused (another Unix user, a missing token, too many clients).
    pub refused: u64,
    /// Blocks refused as another run's or impossible (a count above capacity, ticks going
    /// backwards), and the first one's stream and reason ([`runner::join::BadBlocks`]).
    pub bad_blocks: runner::join::BadBlocks,
}

/// Live-view errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ViewError {
    /// Transport.
    #[error(transparent)]
    Ipc(#[from] IpcError),
    /// The WebSocket server.
    #[error("Foxglove WebSocket server on {addr}: {detail}")]
    Server {
        /// host:port asked for.
        addr: String,
        /// What went wrong.
        detail: String,
    },
    /// Served beyond loopback without a token.
    #[error("a live view on {0} (not a loopback address) needs a token: any machine that reaches it could steer the run")]
    NoToken(String),
    /// Served beyond loopback without TLS, and cleartext not asked for.
    #[error("a live view on {0} (not a loopback address) is served over TLS (`tls`): its token and data would otherwise cross the network in cleartext (set `cleartext` to serve so knowingly)")]
    Cleartext(String),
    /// No run appeared.
    #[error("no run on prefix {0:?} within {1:?}: start the run on that prefix first")]
    NoRun(String, Duration),
}

/// Channel ids of the two topics.
const OVERVIEW_CHANNEL: u32 = 1;
const HEALTH_CHANNEL: u32 = 2;

/// Serves run `o.prefix` until it ends (then `o.linger` more) or `stop` is set; `listening`
/// hears the bound port first.
pub fn serve(
    o: &ViewOptions,
    stop: &AtomicBool,
    listening: impl FnOnce(u16),
) -> Result<ViewReport, ViewError> {
    let loopback = o
        .host
        .parse::<std::net::IpAddr>()
        .is_ok_and(ws::peer::is_loopback)
        || o.host == "localhost";
    if !loopback && o.token.is_none() {
        return Err(ViewError::NoToken(o.host.clone()));
    }
    if !loopback && o.tls.is_none() && !o.cleartext {
        return Err(ViewError::Cleartext(o.host.clone()));
    }
    let ep = Endpoint::open(&o.prefix, &format!("view-{}", std::process::id()))?;
    let tap = Tap::new(&ep)?;
    let (tx, rx) = std::sync::mpsc::channel();
    let mut operator = Operator::new(&ep, rx)?;
    let text = |v: Vec<u8>| String::from_utf8(v).expect("JSON schemas are UTF-8");
    let object = |what: &str| format!(r#"{{"type": "object", "description": "{what}"}}"#);
    let addr = format!("{}:{}", o.host, o.port);
    let server = Front::start(
        FrontOptions {
            name: format!("fts-servo run {}", o.prefix),
            host: o.host.clone(),
            port: o.port,
            metadata: [
                ("fts_servo.prefix".to_owned(), o.prefix.clone()),
                (
                    "fts_servo.contract_version".to_owned(),
                    daq_io::CONTRACT_VERSION.to_string(),
                ),
            ]
            .into(),
            channels: vec![
                Channel {
                    id: OVERVIEW_CHANNEL,
                    topic: messages::OVERVIEW_TOPIC.into(),
                    schema_name: "fts_servo.Overview".into(),
                    schema: text(messages::overview_schema()),
                },
                Channel {
                    id: HEALTH_CHANNEL,
                    topic: messages::HEALTH_TOPIC.into(),
                    schema_name: "fts_servo.Health".into(),
                    schema: text(messages::health_schema()),
                },
            ],
            service: Some(Service {
                id: 1,
                name: STOP_SERVICE.into(),
                type_name: "fts_servo.Stop".into(),
                request_schema: object("empty"),
                response_schema: object("stopped_at_tick: the tick the run ends at"),
            }),
            read_only: o.read_only,
            token: o.token.clone(),
            tls: o.tls.clone(),
        },
        tx,
    )
    .map_err(|e| ViewError::Server {
        addr: addr.clone(),
        detail: e.to_string(),
    })?;
    listening(server.port());

    let mut join = Joiner::default();
    let mut bin = OverviewBin::default();
    let mut report = ViewReport::default();
    let mut run_id = None;
    let mut bins = 0u64;
    let waiting = Instant::now();
    let mut ended_at: Option<Instant> = None;
    let mut last_data = Instant::now();
    let mut publish = |t_ns: u64, ov: &recorder::Overview, report: &mut ViewReport| {
        bins += 1;
        if bins.is_multiple_of(u64::from(o.every.max(1))) {
            server.publish(OVERVIEW_CHANNEL, t_ns, &messages::overview(t_ns, ov));
            report.overview_samples += 1;
        }
    };
    while !stop.load(Ordering::Relaxed) {
        let mut got = false;
        for b in take_waiting(&tap.telemetry) {
            got = true;
            join.telemetry(&b);
        }
        for b in take_waiting(&tap.truth) {
            got = true;
            join.truth(&b);
        }
        if let (None, Some(id)) = (run_id, join.run_id()) {
            run_id = Some(id);
            operator.set_metadata(metadata(&ep, id));
        }
        if got {
            last_data = Instant::now();
        }
        // The recorder's rule (frames are never made from truth merely ahead of its
        // telemetry); a run gone silent for the recorder's timeout is over too.
        let silent = last_data.elapsed() > runner::hil::RECORDER_TIMEOUT;
        let end = join.run_over() || (run_id.is_some() && silent);
        while let Some(h) = take(&tap.health) {
            // Health reports are stamped when the view saw them (wall clock, ns).
            let now_ns = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos() as u64);
            server.publish(HEALTH_CHANNEL, now_ns, &messages::health(&h));
        }
        join.drain(end, |f| {
            report.ticks += 1;
            if let Some((t, ov)) = bin.add(&f) {
                publish(t, &ov, &mut report);
            }
        });
        if end && ended_at.is_none() {
            if let Some((t, ov)) = bin.take() {
                publish(t, &ov, &mut report);
            }
            report.run_ended = true;
            ended_at = Some(Instant::now());
        }
        let (values, problems) = operator.poll(&ep);
        if !values.is_empty() {
            server.publish_parameters(&values);
        }
        for p in problems {
            server.publish_status(1, &p);
        }
        if ended_at.is_some_and(|t| t.elapsed() >= o.linger) {
            break;
        }
        if run_id.is_none() && waiting.elapsed() > o.startup_timeout {
            server.stop();
            return Err(ViewError::NoRun(o.prefix.clone(), o.startup_timeout));
        }
        if !got {
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    report.dropped = join.dropped();
    report.bad_blocks = join.bad_blocks().clone();
    report.applied_gains = operator.applied_gains.clone();
    report.refused = server.refused();
    server.stop();
    Ok(report)
}

/// The run's metadata as read-only parameters.
fn metadata(ep: &Endpoint, run_id: u64) -> Vec<Parameter> {
    let peers: Vec<String> = ep
        .peers()
        .iter()
        .map(|p| format!("{} (pid {})", p.role, p.pid))
        .collect();
    vec![
        Parameter::string("run.prefix", ep.prefix()),
        Parameter::string("run.id", format!("{run_id:016x}")),
        Parameter::string("run.processes", peers.join(", ")),
        Parameter::integer("run.contract_version", i64::from(daq_io::CONTRACT_VERSION)),
    ]
}
