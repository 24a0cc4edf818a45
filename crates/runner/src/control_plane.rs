//! The controller's side of a run's control plane, for any process that runs a [`ServoLoop`]:
//! `servo controller`, or a DAQ daemon that embeds the loop (`examples/embedded_daq.rs`).
//! Gain changes are checked against the loop's stability margin ([`gain_range`]) and
//! acknowledged; STOP requests are acknowledged when the process also serves the plant; health
//! reports carry the tick statistics.

use crate::error::RunError;
use crate::gain_range::{gain_range, GainRange};
use crate::plan::Plan;
use crate::servo_loop::ServoLoop;
use daq_io::contract::{command, role, state};
use daq_io::ipc::{leaf, take, Endpoint, Sender, Subscriber};
use daq_io::{ack_status, Ack, Control, Health, TickStats};
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
        })
    }

    /// At the first tick: sets up the connections, reports running, drops stale requests.
    pub fn begin(&mut self) {
        self.health_pub.connect();
        self.health_pub.send(self.health);
        self.health_pub.prepare();
        while take(&self.control).is_some() {}
        self.start = Instant::now();
    }

    /// Every [`SERVICE_TICKS`] ticks: applies gain changes to `servo` from tick `tick`,
    /// acknowledges requests, publishes health with `stats`. Returns a STOP to act on.
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
            self.ack.send(ack);
            self.ack.prepare();
        }
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
