//! The control plane's client: requests to a running HIL run — start, stop, a gain scale, a
//! controller load — each paired by its id with the acknowledgement of the process that acts
//! on it, and what that acknowledgement means in words. `servo ctl`, the live view and Python
//! use it; none of it touches the servo path.

use crate::contract::{ack_status, command};
use crate::ipc::{leaf, take, ControlSender, Endpoint, IpcError, Publisher, Subscriber};
use crate::{Ack, Control, ControllerLoad};
use std::time::{Duration, Instant};

/// A request to a running run.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// Start the plant (a run started paused).
    Start,
    /// End the run at the next tick.
    Stop,
    /// Scale the controller's output by this factor (dimensionless); the controller applies
    /// it only when the loop keeps its 6 dB gain margin.
    Gain(f64),
    /// Replace the feedback controller by the controller file of these bytes (at most
    /// [`crate::MAX_LOAD_BYTES`]), checked by the controller against the running loop.
    Load(Vec<u8>),
}

impl Request {
    /// The process that acts on it and acknowledges it: `plant` or `controller`.
    pub fn target(&self) -> &'static str {
        match self {
            Request::Start | Request::Stop => "plant",
            Request::Gain(_) | Request::Load(_) => "controller",
        }
    }

    /// The topic (leaf) the request travels on.
    fn leaf(&self) -> &'static str {
        match self {
            Request::Load(_) => leaf::CONTROLLER_LOAD,
            _ => leaf::CONTROL,
        }
    }
}

/// A request that did not reach its acknowledgement.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// No process of the run that the request is for.
    #[error("no run on prefix {prefix:?}: no live {target} (start one with `servo run --hil --prefix {prefix}`)")]
    NoRun {
        /// The run's prefix.
        prefix: String,
        /// The process looked for.
        target: &'static str,
    },
    /// The process does not listen for requests (yet).
    #[error("the {target} of run {prefix:?} does not listen on {leaf} (still starting?)")]
    NotListening {
        /// The run's prefix.
        prefix: String,
        /// The process.
        target: &'static str,
        /// The topic.
        leaf: &'static str,
    },
    /// The transport took no sample for the controller load (its queue full).
    #[error("the transport refused the controller load")]
    LoadRefused,
    /// A controller file too large to travel.
    #[error("a controller load holds at most {} bytes", crate::MAX_LOAD_BYTES)]
    LoadTooLarge,
    /// The answer did not come in time.
    #[error("no acknowledgement from the {target} of run {prefix:?} within {waited_s} s (is it still running?)")]
    NoAnswer {
        /// The run's prefix.
        prefix: String,
        /// The process.
        target: &'static str,
        /// How long it waited, s.
        waited_s: f64,
    },
    /// The transport failed.
    #[error(transparent)]
    Ipc(#[from] IpcError),
}

/// Sends requests over a run's control plane and hears the acknowledgements (each carries the
/// id of the request it answers).
pub struct ControlClient {
    control: ControlSender,
    load: Option<Publisher<ControllerLoad>>,
    acks: Subscriber<Ack>,
}

impl ControlClient {
    /// A client of the run `ep` joined.
    pub fn new(ep: &Endpoint) -> Result<Self, IpcError> {
        Ok(ControlClient {
            control: ControlSender::new(ep)?,
            load: None,
            acks: ep.subscriber::<Ack>(leaf::ACK)?,
        })
    }

    /// Sends `r` and returns its id, which its acknowledgement carries. The publisher of a
    /// load lives as long as the client (iceoryx2 takes a sample back from the subscribers
    /// when its publisher goes).
    pub fn send(&mut self, ep: &Endpoint, r: &Request) -> Result<u64, ControlError> {
        let id = crate::peers::random_id();
        let (command, value) = match r {
            Request::Start => (command::START, 0.0),
            Request::Stop => (command::STOP, 0.0),
            Request::Gain(scale) => (command::SET_GAIN_SCALE, *scale),
            Request::Load(bytes) => {
                let load = ControllerLoad::new(id, bytes).ok_or(ControlError::LoadTooLarge)?;
                if self.load.is_none() {
                    self.load = Some(ep.publisher(leaf::CONTROLLER_LOAD)?);
                }
                let publisher = self.load.as_ref().expect("made above");
                if !crate::ipc::send(publisher, load) {
                    return Err(ControlError::LoadRefused);
                }
                return Ok(id);
            }
        };
        self.control.send(Control {
            command,
            value,
            id,
            ..Default::default()
        })?;
        Ok(id)
    }

    /// The next acknowledgement heard on the run (of any client's request: match its `id`).
    pub fn next_ack(&self) -> Option<Ack> {
        take(&self.acks)
    }
}

/// Sends `r` to the run of `ep` (prefix `prefix`) and waits up to `timeout` for its
/// acknowledgement: at once an error when no process of the run is there; while the run's
/// processes are starting, waits for the target and for it to listen.
pub fn request(
    ep: &Endpoint,
    prefix: &str,
    r: &Request,
    timeout: Duration,
) -> Result<Ack, ControlError> {
    let target = r.target();
    let start = Instant::now();
    loop {
        let peers = ep.peers();
        if peers.iter().any(|p| p.role == target) {
            break;
        }
        if peers.is_empty() || start.elapsed() >= timeout {
            return Err(ControlError::NoRun {
                prefix: prefix.into(),
                target,
            });
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut client = ControlClient::new(ep)?;
    // Sent once the run listens: a message before any subscriber is lost.
    let heard = match r {
        Request::Load(_) => ep.await_subscriber::<ControllerLoad>(r.leaf(), timeout)?,
        _ => ep.await_subscriber::<Control>(r.leaf(), timeout)?,
    };
    if !heard {
        return Err(ControlError::NotListening {
            prefix: prefix.into(),
            target,
            leaf: r.leaf(),
        });
    }
    let id = client.send(ep, r)?;
    while start.elapsed() < timeout {
        while let Some(a) = client.next_ack() {
            if a.id == id {
                return Ok(a);
            }
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Err(ControlError::NoAnswer {
        prefix: prefix.into(),
        target,
        waited_s: timeout.as_secs_f64(),
    })
}

/// What the acknowledgement `a` of a gain change to `scale` means: the line to show when it
/// was applied, or why it was refused.
pub fn gain_outcome(scale: f64, a: &Ack) -> Result<String, String> {
    let margin_db = 20.0 * libm::log10(a.unstable_at);
    match a.status {
        ack_status::APPLIED => Ok(format!(
            "gain ×{scale} applied from tick {} (allowed ×{:.3}–×{:.3}: the loop goes unstable above ×{:.3}, {margin_db:.1} dB of gain margin at ×1)",
            a.tick, a.low, a.high, a.unstable_at
        )),
        ack_status::REFUSED_MARGIN => Err(format!(
            "gain ×{scale} refused: the loop goes unstable above ×{:.3} (gain margin {margin_db:.1} dB at ×1); changes keep a 6 dB margin: allowed ×{:.3}–×{:.3}",
            a.unstable_at, a.low, a.high
        )),
        _ => Err(format!("gain ×{scale} refused: not a finite number")),
    }
}

/// What the acknowledgement `a` of a controller load of `name` means; a refusal for another
/// plant or rate names the file's `made_for` as `made_for` describes it.
pub fn load_outcome(name: &str, a: &Ack, made_for: &str) -> Result<String, String> {
    match a.status {
        ack_status::APPLIED => Ok(format!(
            "controller {name} took the loop at tick {}, bumplessly (the old output fades over 5 ms); closed-loop spectral radius {:.6}; gain scale now allowed ×{:.3}–×{:.3}",
            a.tick, a.value, a.low, a.high
        )),
        ack_status::REFUSED_PROVENANCE => Err(format!(
            "controller {name} refused: made for another plant or rate than the run's ({made_for}); the controller process names both"
        )),
        ack_status::REFUSED_MARGIN if a.value >= 1.0 => Err(format!(
            "controller {name} refused: the closed loop on the run's model would be unstable (spectral radius {:.6} ≥ 1); the running controller stays",
            a.value
        )),
        ack_status::REFUSED_MARGIN => Err(format!(
            "controller {name} refused: stable at gain ×1 but not at the run's present gain scale; reset it (`servo ctl gain 1`) and load again"
        )),
        _ => Err(format!(
            "controller {name} refused: not a controller this run can build, a change of feedforward (a load swaps the feedback controller only), or another load is in progress (the controller process says which)"
        )),
    }
}

/// What the acknowledgement `a` of a start or stop means.
pub fn plant_outcome(r: &Request, a: &Ack) -> String {
    match r {
        Request::Start => "start applied: the plant runs".into(),
        _ => format!("stop applied: the run ends at tick {}", a.tick),
    }
}
