//! The controller's side of a run's control plane, for any process that runs a [`ServoLoop`]:
//! `servo controller`, or a DAQ daemon that embeds the loop (`examples/embedded_daq.rs`).
//! Gain changes are checked against the loop's stability margin ([`gain_range`]) and
//! acknowledged; controllers sent to the running loop (`servo ctl load`) are prepared off the
//! ticking thread ([`crate::hot_swap`]), handed over bumplessly at a tick boundary and
//! acknowledged with that tick, or refused with the reason's status; STOP requests are
//! acknowledged when the process also serves the plant; health reports carry the tick
//! statistics.

use crate::controller::Controller;
use crate::error::RunError;
use crate::gain_range::{gain_range, GainRange};
use crate::hot_swap::{Loader, Prepared};
use crate::plan::Plan;
use crate::servo_loop::ServoLoop;
use daq_io::contract::{command, role, state};
use daq_io::ipc::{leaf, take, Endpoint, Sender, Subscriber};
use daq_io::{ack_status, Ack, Control, ControllerLoad, Health, TickStats};
use std::time::Instant;

/// Ticks between two looks at the control plane (and two health reports): 10 ms at 199.6 kHz.
pub const SERVICE_TICKS: u64 = 2048;

/// What the control plane asked for, beyond what it applied itself.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// Nothing.
    None,
    /// End the run at this tick boundary; the [`daq_io::stop_cause`].
    Stop(u32),
}

/// The control-plane ports and state of a controller process.
pub struct ControlPlane {
    gains: GainRange,
    control: Subscriber<Control>,
    ack: Sender<Ack>,
    health_pub: Sender<Health>,
    health: Health,
    serves_plant: bool,
    start: Instant,
    loads: Subscriber<ControllerLoad>,
    loader: Loader,
    /// The load request the loader works on.
    loading: Option<u64>,
    /// A controller handed over, acknowledged once its tick is known: (request, spectral
    /// radius of the new loop).
    handing_over: Option<(u64, f64)>,
    /// A replaced controller the loader could not take yet (dropped there later).
    parked: Option<Controller>,
}

impl ControlPlane {
    /// Joins the control plane of the run of `ep` for the loop of `plan` (refused if that loop
    /// is unstable). `serves_plant`: this process also closes the loop on the hardware (an
    /// embedding DAQ daemon) and so takes STOP itself.
    pub fn new(ep: &Endpoint, plan: &Plan, serves_plant: bool) -> Result<Self, RunError> {
        Ok(ControlPlane {
            gains: gain_range(plan)?,
            control: ep.subscriber::<Control>(leaf::CONTROL)?,
            ack: Sender::new(ep.publisher::<Ack>(leaf::ACK)?),
            health_pub: Sender::new(ep.publisher::<Health>(leaf::HEALTH)?),
            health: Health {
                role: if serves_plant {
                    role::PLANT
                } else {
                    role::CONTROLLER
                },
                state: state::RUNNING,
                ..Default::default()
            },
            serves_plant,
            start: Instant::now(),
            loads: ep.subscriber::<ControllerLoad>(leaf::CONTROLLER_LOAD)?,
            loader: Loader::start(plan, ep.prefix()),
            loading: None,
            handing_over: None,
            parked: None,
        })
    }

    /// At the first tick: sets up the connections, reports running, drops stale requests.
    pub fn begin(&mut self) {
        self.health_pub.connect();
        self.health_pub.send(self.health);
        self.health_pub.prepare();
        while take(&self.control).is_some() {}
        while let Ok(Some(_)) = self.loads.receive() {}
        self.start = Instant::now();
    }

    /// The controller-load part of [`ControlPlane::service`]: acknowledges a handover once it
    /// took effect, passes a new request to the loader (one at a time), hands a prepared
    /// controller to `servo` or refuses it, and sends replaced controllers to be dropped.
    fn deploy(&mut self, servo: &mut ServoLoop, tick: u64) {
        if let Some(old) = self.parked.take().or_else(|| servo.take_replaced()) {
            self.parked = self.loader.dispose(old);
        }
        if let (Some((id, radius)), Some(at)) = (self.handing_over, servo.handed_over_at()) {
            self.handing_over = None;
            let ack = self.load_ack(id, at, ack_status::APPLIED, radius);
            self.reply(ack);
        }
        while let Ok(Some(request)) = self.loads.receive() {
            let busy = self.loading.is_some() || self.handing_over.is_some();
            if !busy && self.loader.submit(request.id, request.file()) {
                self.loading = Some(request.id);
            } else {
                let ack = self.load_ack(request.id, tick, ack_status::REFUSED_INVALID, f64::NAN);
                self.reply(ack);
            }
        }
        let Some(prepared) = self.loader.poll() else {
            return;
        };
        self.loading = None;
        match prepared {
            Prepared::Ready {
                id,
                controller,
                gains,
                spectral_radius,
            } if gains.allows(servo.gain_scale()) => {
                servo.hand_over(controller);
                self.gains = gains;
                self.handing_over = Some((id, spectral_radius));
            }
            Prepared::Ready {
                id,
                controller,
                spectral_radius,
                ..
            } => {
                // Stable at scale 1, not at the scale the run is at now.
                self.parked = self.loader.dispose(controller);
                let ack = self.load_ack(id, tick, ack_status::REFUSED_MARGIN, spectral_radius);
                self.reply(ack);
            }
            Prepared::Refused {
                id,
                status,
                spectral_radius,
            } => {
                let ack = self.load_ack(id, tick, status, spectral_radius);
                self.reply(ack);
            }
        }
    }

    /// The answer to load request `id` at `tick`: `status`, the new loop's spectral radius as
    /// the value, the gain range the run now has.
    fn load_ack(&self, id: u64, tick: u64, status: u32, spectral_radius: f64) -> Ack {
        Ack {
            id,
            tick,
            value: spectral_radius,
            low: self.gains.low(),
            high: self.gains.high(),
            unstable_at: self.gains.unstable_above,
            command: command::LOAD_CONTROLLER,
            status,
            role: role::CONTROLLER,
            reserved: 0,
        }
    }

    fn reply(&mut self, ack: Ack) {
        self.ack.send(ack);
        self.ack.prepare();
    }

    /// Every [`SERVICE_TICKS`] ticks: applies gain changes to `servo` from tick `tick`, moves
    /// controller loads along (`ControlPlane::deploy`), acknowledges requests, publishes
    /// health with `stats`. Returns a STOP to act on.
    pub fn service(
        &mut self,
        servo: &mut ServoLoop,
        tick: u64,
        overruns: u64,
        stats: &TickStats,
    ) -> Request {
        let mut request = Request::None;
        while let Some(c) = take(&self.control) {
            let ack = match c.command {
                command::SET_GAIN_SCALE => {
                    let ack = gain_change(&self.gains, &c, tick);
                    if ack.status == ack_status::APPLIED {
                        servo.set_gain_scale(c.value);
                    }
                    ack
                }
                command::STOP if self.serves_plant => {
                    if request == Request::None {
                        request = Request::Stop(daq_io::stop_cause::of_value(c.value));
                    }
                    plant_reply(&c, tick)
                }
                command::START if self.serves_plant => plant_reply(&c, tick),
                _ => continue, // the plant's
            };
            self.reply(ack);
        }
        self.deploy(servo, tick);
        self.report(tick, overruns, stats);
        request
    }

    /// Publishes health: `tick`, `overruns`, the statistics.
    pub fn report(&mut self, tick: u64, overruns: u64, stats: &TickStats) {
        self.health.ticks = tick;
        self.health.overruns = overruns;
        self.health.wall_s = self.start.elapsed().as_secs_f64();
        stats.report(&mut self.health);
        self.health_pub.send(self.health);
        self.health_pub.prepare();
    }

    /// The final health report: done or faulted, with `faults` bits and the stop cause.
    pub fn finish(
        &mut self,
        tick: u64,
        overruns: u64,
        stats: &TickStats,
        faults: u32,
        stop_cause: u32,
    ) {
        self.health.state = state::ended(faults);
        self.health.faults = faults;
        self.health.stop_cause = stop_cause;
        self.report(tick, overruns, stats);
    }
}

/// The plant's acknowledgement of STOP / START.
fn plant_reply(c: &Control, tick: u64) -> Ack {
    Ack::to(c, tick, ack_status::APPLIED, role::PLANT)
}

/// The answer to gain change `c` seen before tick `tick` (applied from that tick if allowed):
/// refused when not a number or outside the range that keeps [`crate::gain_range::MARGIN`].
fn gain_change(gains: &GainRange, c: &Control, tick: u64) -> Ack {
    Ack {
        low: gains.low(),
        high: gains.high(),
        unstable_at: gains.unstable_above,
        ..Ack::to(
            c,
            tick,
            if !c.value.is_finite() {
                ack_status::REFUSED_INVALID
            } else if gains.allows(c.value) {
                ack_status::APPLIED
            } else {
                ack_status::REFUSED_MARGIN
            },
            role::CONTROLLER,
        )
    }
}
