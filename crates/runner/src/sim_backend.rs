//! The simulated stage (plant-sim) behind daq-io's [`Backend`]: what the in-process run and
//! `servo plant` serve, so both compute bit-identical ticks.

use crate::config::Scenario;
use crate::machining::Workpiece;
use crate::plan::Plan;
use daq_io::{Backend, Sensor, Truth};
use plant_sim::practice::PracticeStage;
use plant_sim::Simulator;

/// The simulated stage as a daq-io backend (keeps the last step's truth), with the part on
/// the spindle when machining.
pub struct SimBackend {
    stage: Stage,
    truth: Truth,
    workpiece: Option<Workpiece>,
    tick: u64,
}

/// Which stage is simulated.
// One per run, made once: the configured stage stays inline (no indirection on its tick).
#[allow(clippy::large_enum_variant)]
enum Stage {
    /// The configured one.
    Configured(Simulator),
    /// The practice stage of `run.practice_seed` (the configured plant is the model).
    Practice(Box<PracticeStage>),
}

impl SimBackend {
    /// Wraps `sim` (no spindle).
    pub fn new(sim: Simulator) -> Self {
        SimBackend {
            stage: Stage::Configured(sim),
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
        let stage = match plan.config.run.practice_seed {
            None => Stage::Configured(plan.sim.clone()),
            Some(seed) => Stage::Practice(Box::new(
                PracticeStage::new(&plan.config.plant, seed)
                    .expect("the plan drew this practice stage without error"),
            )),
        };
        SimBackend {
            stage,
            truth: Truth::default(),
            workpiece,
            tick: 0,
        }
    }

    /// The simulator (of the drawn stage, for the practice stage).
    pub fn sim(&self) -> &Simulator {
        match &self.stage {
            Stage::Configured(s) => s,
            Stage::Practice(p) => p.simulator(),
        }
    }
}

impl Backend for SimBackend {
    #[inline]
    fn step(&mut self, dac_v: f64) -> Sensor {
        let force = self
            .workpiece
            .as_ref()
            .map_or(0.0, |w| w.cutting_force_n(self.tick));
        let mut sample = match &mut self.stage {
            Stage::Configured(sim) => {
                let (s, t) = sim.step_with_force(dac_v, force);
                self.truth = t.to_contract(s.time_s);
                Sensor {
                    time_s: s.time_s,
                    gap_v: s.gap_v,
                    accel_v: s.accel_v,
                    flags: s.flags,
                    ..Default::default()
                }
            }
            Stage::Practice(p) => {
                let s = p.step_with_force(dac_v, force);
                self.truth = Backend::truth(&**p).unwrap_or_default();
                s
            }
        };
        self.tick += 1;
        sample.encoder_count = self
            .workpiece
            .as_ref()
            .map_or(0, |w| w.encoder_count(self.tick));
        sample
    }

    fn truth(&self) -> Option<Truth> {
        Some(self.truth)
    }
}
