//! The simulated stage (plant-sim) behind daq-io's [`Backend`]: what the in-process run,
//! `servo plant` and libfts_plant serve, so all compute bit-identical ticks.

use crate::surface::LoadedSurface;
use crate::workpiece::Workpiece;
use crate::{ConfigError, Origin, RunConfig, Scenario};
use daq_io::{Backend, Sensor, Truth};
use plant_sim::practice::PracticeStage;
use plant_sim::Simulator;

/// The simulated stage of a run as a daq-io backend: the simulator or the practice stage, with
/// the part on the spindle when machining.
pub struct SimBackend {
    stage: Stage,
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
    /// The stage of the run `config` (its checked values at `at`): the seeded simulator `sim`
    /// with the scenario's cutting profile, the practice stage of `run.practice_seed` instead
    /// when set, and the spindle and part of a machining scenario cut along `surface`.
    pub fn for_run(
        config: &RunConfig,
        at: &Origin,
        sim: Simulator,
        surface: Option<LoadedSurface>,
    ) -> Result<Self, ConfigError> {
        let workpiece = match (&config.scenario, surface) {
            (Scenario::Machine(m), Some(surface)) => {
                Some(Workpiece::new(m, surface, config.plant.period_s()))
            }
            _ => None,
        };
        let stage = match config.run.practice_seed {
            None => Stage::Configured(sim),
            Some(seed) => Stage::Practice(Box::new(practice_stage(config, at, seed)?)),
        };
        Ok(SimBackend {
            stage,
            workpiece,
            tick: 0,
        })
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
            Stage::Configured(sim) => sim.step_sensor(dac_v, force),
            Stage::Practice(p) => p.step_with_force(dac_v, force),
        };
        self.tick += 1;
        sample.encoder_count = self
            .workpiece
            .as_ref()
            .map_or(0, |w| w.encoder_count(self.tick));
        sample
    }

    fn truth(&self) -> Option<Truth> {
        match &self.stage {
            Stage::Configured(sim) => Backend::truth(sim),
            Stage::Practice(p) => Backend::truth(&**p),
        }
    }
}

/// The practice stage of `seed` drawn around the plant of `config`, its error at
/// `run.practice_seed`.
pub fn practice_stage(
    config: &RunConfig,
    at: &Origin,
    seed: u64,
) -> Result<PracticeStage, ConfigError> {
    PracticeStage::new(&config.plant, seed, config.run.practice_effects).map_err(|e| {
        at.invalid(
            "run.practice_seed",
            seed,
            &format!("a seed whose drawn stage simulates ({e})"),
        )
    })
}
