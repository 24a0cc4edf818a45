//! The simulated stage (plant-sim) behind daq-io's [`Backend`]: what the in-process run and
//! `servo plant` serve, so both compute bit-identical ticks.

use crate::config::Scenario;
use crate::machining::Workpiece;
use crate::plan::Plan;
use daq_io::{Backend, Sensor, Truth};
use plant_sim::Simulator;

/// The simulated stage as a daq-io backend (keeps the last step's truth), with the part on
/// the spindle when machining.
pub struct SimBackend {
    sim: Simulator,
    truth: Truth,
    workpiece: Option<Workpiece>,
    tick: u64,
}

impl SimBackend {
    /// Wraps `sim` (no spindle).
    pub fn new(sim: Simulator) -> Self {
        SimBackend {
            sim,
            truth: Truth::default(),
            workpiece: None,
            tick: 0,
        }
    }

    /// The stage of the run `plan`: its seeded simulator with the scenario's cutting profile,
    /// and the spindle and part of a machining scenario.
    pub fn for_run(plan: &Plan) -> Self {
        let workpiece = match (&plan.config.scenario, &plan.surface) {
            (Scenario::Machine(m), Some(surface)) => {
                Some(Workpiece::new(m, surface.clone(), plan.period_s()))
            }
            _ => None,
        };
        SimBackend {
            workpiece,
            ..SimBackend::new(plan.sim.clone())
        }
    }

    /// The simulator.
    pub fn sim(&self) -> &Simulator {
        &self.sim
    }
}

impl Backend for SimBackend {
    #[inline]
    fn step(&mut self, dac_v: f64) -> Sensor {
        let force = self
            .workpiece
            .as_ref()
            .map_or(0.0, |w| w.cutting_force_n(self.tick));
        let (s, t) = self.sim.step_with_force(dac_v, force);
        self.tick += 1;
        self.truth = t.to_contract(s.time_s);
        Sensor {
            seq: 0,
            time_s: s.time_s,
            gap_v: s.gap_v,
            accel_v: s.accel_v,
            encoder_count: self
                .workpiece
                .as_ref()
                .map_or(0, |w| w.encoder_count(self.tick)),
            flags: s.flags,
            ..Default::default()
        }
    }

    fn truth(&self) -> Option<Truth> {
        Some(self.truth)
    }
}
