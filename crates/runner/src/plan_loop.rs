//! A plan's loop as the runtime runs it: the runtime's [`Servo`] built from the plan's
//! deployment, and — for a machining run — the surface reference it reads ahead (the spindle
//! tracked from each sample's encoder count). Shared by the in-process run and the HIL
//! controller process so both compute bit-identical results.

use crate::machining::SurfaceReference;
use crate::plan::{located_in_run, Plan};
use daq_io::{flags, Command, Sensor, Telemetry};
use run_config::{ConfigError, Scenario};
use servo_config::Deployment;
use servo_runtime::{Servo, TripCause};

/// The runtime's loop with the run's trajectory.
pub struct PlanLoop {
    servo: Servo,
    surface: Option<Box<SurfaceReference>>,
}

impl PlanLoop {
    /// The loop of `plan` in its initial state.
    pub fn new(plan: &Plan) -> Result<Self, ConfigError> {
        Self::with_deployment(plan, &plan.deployment)
    }

    /// The loop of `plan` running `deployment` (the plan's, with its checked stability).
    pub fn with_deployment(plan: &Plan, deployment: &Deployment) -> Result<Self, ConfigError> {
        let servo = Servo::new(deployment).map_err(|e| located_in_run(&e, &plan.origin))?;
        let surface = match &plan.config.scenario {
            Scenario::Machine(m) => {
                let surface = plan
                    .surface
                    .clone()
                    .expect("a machining plan has its surface");
                let r =
                    SurfaceReference::new(m, surface, plan.period_s(), plan.repetitive.as_ref())
                        .map_err(|e| plan.origin.invalid("scenario", e, "see the message"))?;
                Some(Box::new(r))
            }
            _ => None,
        };
        Ok(PlanLoop { servo, surface })
    }

    /// One tick for sample `s`: the command and the tick's telemetry (both None when `s` closes
    /// the run). Allocation-free.
    #[inline]
    pub fn tick(&mut self, s: &Sensor) -> (Option<Command>, Option<Telemetry>) {
        let command = match &mut self.surface {
            Some(r) => self.servo.tick_with(s, &mut **r),
            None => self.servo.tick(s),
        };
        let command = (s.flags & flags::END == 0).then_some(command);
        (command, self.servo.telemetry().copied())
    }

    /// The repetitive controller's learned table (m per bin), if the run has one.
    pub fn repetitive_table(&self) -> Option<&[f64]> {
        self.surface.as_ref().and_then(|r| r.repetitive_table())
    }

    /// The cause and tick of the machine-protection trip, if the loop tripped.
    pub fn trip(&self) -> Option<(TripCause, u64)> {
        self.servo.status().trip.map(|t| (t.cause, t.tick))
    }

    /// Whether the run should end: the loop tripped and has held the safe state for
    /// `protection.after_trip_s`.
    #[inline]
    pub fn run_over(&self) -> bool {
        self.servo.status().trip_settled
    }

    /// The runtime's loop (to serve it, to steer it).
    pub fn servo_mut(&mut self) -> &mut Servo {
        &mut self.servo
    }
}
