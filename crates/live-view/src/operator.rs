//! The operator's controls in Foxglove, bound to the run's control plane: the `gain_scale`
//! parameter (a set is `servo ctl gain`: the controller applies it only when the loop keeps
//! its 6 dB gain margin, and the parameter takes the value the run acknowledged) and the
//! `stop` service (`servo ctl stop`). Read-only parameters carry the run's metadata. Requests
//! are queued by the server's threads and answered from the view's own loop, which owns the
//! control plane; nothing here touches the servo path.

use crate::ws::protocol::{Parameter, ParameterValue};
use crate::ws::{Ask, Reply, ServiceReply};
use daq_io::contract::ack_status;
use daq_io::control_client::{gain_outcome, ControlClient, Request};
use daq_io::ipc::{Endpoint, IpcError};
use std::sync::mpsc::Receiver;
use std::time::{Duration, Instant};

/// Name of the gain parameter (dimensionless scale of the controller output).
pub const GAIN_SCALE: &str = "gain_scale";
/// Name of the stop service.
pub const STOP_SERVICE: &str = "stop";
/// How long a request waits for the run's acknowledgement.
pub const ACK_TIMEOUT: Duration = Duration::from_secs(5);

/// What waits for an acknowledgement.
enum Waiting {
    Gain(f64, Reply),
    Stop(ServiceReply),
}

/// The control-plane side: sends requests, pairs acknowledgements by id, answers.
pub struct Operator {
    asks: Receiver<Ask>,
    client: ControlClient,
    pending: Vec<(u64, Instant, Waiting)>,
    /// The gain scale the run last acknowledged (1 until one was applied).
    gain_scale: f64,
    /// Read-only metadata parameters (`run.*`).
    metadata: Vec<Parameter>,
    /// Gain changes the run applied through this view.
    pub applied_gains: Vec<f64>,
    /// Messages for the clients' problems panel (refusals, timeouts).
    problems: Vec<String>,
}

impl Operator {
    /// Answers the requests of `asks` over run `ep`'s control plane.
    pub fn new(ep: &Endpoint, asks: Receiver<Ask>) -> Result<Self, IpcError> {
        Ok(Operator {
            asks,
            client: ControlClient::new(ep)?,
            pending: Vec::new(),
            gain_scale: 1.0,
            metadata: Vec::new(),
            applied_gains: Vec::new(),
            problems: Vec::new(),
        })
    }

    /// Sets the `run.*` metadata parameters.
    pub fn set_metadata(&mut self, metadata: Vec<Parameter>) {
        self.metadata = metadata;
    }

    fn gain(&self) -> Parameter {
        Parameter::float64(GAIN_SCALE, self.gain_scale)
    }

    fn send(&mut self, ep: &Endpoint, request: Request, waiting: Waiting) {
        match self.client.send(ep, &request) {
            Ok(id) => self.pending.push((id, Instant::now(), waiting)),
            Err(e) => self.answer_failure(waiting, format!("the control plane refused it: {e}")),
        }
    }

    fn answer_failure(&mut self, waiting: Waiting, why: String) {
        match waiting {
            Waiting::Gain(v, r) => {
                r.respond(vec![self.gain()]);
                self.problems
                    .push(format!("gain_scale ×{v} not applied: {why}"));
            }
            Waiting::Stop(r) => r.respond_err(why),
        }
    }

    /// Handles queued requests (sent over run `ep`'s control plane) and arrived
    /// acknowledgements; returns the parameter values to publish to every client (a gain the
    /// run applied) and the problems to show.
    pub fn poll(&mut self, ep: &Endpoint) -> (Vec<Parameter>, Vec<String>) {
        while let Ok(ask) = self.asks.try_recv() {
            match ask {
                Ask::Get(names, r) => {
                    let all: Vec<Parameter> = std::iter::once(self.gain())
                        .chain(self.metadata.iter().cloned())
                        .collect();
                    r.respond(
                        all.into_iter()
                            .filter(|p| names.is_empty() || names.contains(&p.name))
                            .collect(),
                    );
                }
                Ask::Set(params, r) => {
                    let value = params
                        .iter()
                        .find(|p| p.name == GAIN_SCALE)
                        .and_then(|p| match p.value {
                            Some(ParameterValue::Float64(v)) => Some(v),
                            Some(ParameterValue::Integer(v)) => Some(v as f64),
                            _ => None,
                        });
                    match value {
                        Some(v) => self.send(ep, Request::Gain(v), Waiting::Gain(v, r)),
                        // Only gain_scale can be set; the metadata is read-only.
                        None => r.respond(vec![self.gain()]),
                    }
                }
                Ask::Call(r) => self.send(ep, Request::Stop, Waiting::Stop(r)),
            }
        }
        let mut publish = Vec::new();
        while let Some(a) = self.client.next_ack() {
            let Some(i) = self.pending.iter().position(|(id, ..)| *id == a.id) else {
                continue;
            };
            let (_, _, waiting) = self.pending.swap_remove(i);
            match (waiting, a.status) {
                (Waiting::Gain(v, r), ack_status::APPLIED) => {
                    self.gain_scale = v;
                    self.applied_gains.push(v);
                    r.respond(vec![self.gain()]);
                    publish.push(self.gain());
                }
                (Waiting::Gain(v, r), _) => {
                    r.respond(vec![self.gain()]);
                    if let Err(why) = gain_outcome(v, &a) {
                        self.problems.push(why);
                    }
                }
                (Waiting::Stop(r), _) => {
                    r.respond_ok(format!("{{\"stopped_at_tick\": {}}}", a.tick).into_bytes())
                }
            }
        }
        let now = Instant::now();
        let (late, waiting): (Vec<_>, Vec<_>) = std::mem::take(&mut self.pending)
            .into_iter()
            .partition(|(_, at, _)| now.duration_since(*at) > ACK_TIMEOUT);
        self.pending = waiting;
        for (_, _, w) in late {
            self.answer_failure(w, format!("no acknowledgement within {ACK_TIMEOUT:?}"));
        }
        (publish, std::mem::take(&mut self.problems))
    }
}
