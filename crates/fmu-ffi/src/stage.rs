//! The stage unit: the seeded simulator of the unit's plant, the DAC command and an external
//! force held over each tick, the readings at its end.

use crate::model::{Model, Value};
use daq_io::{Backend, Sensor};
use fmu::variables::{plant_parameters, plant_with, stage, stage_variables, Scalar};
use fmu::Variable;
use plant_sim::cutting::CuttingProfile;
use plant_sim::model::ModelError;
use plant_sim::sim::SimError;
use plant_sim::{PlantParams, Simulator};

/// The stage unit.
pub struct StageUnit {
    vars: Vec<Variable>,
    base: PlantParams,
    start_seed: u64,
    start_scalars: Vec<(String, Scalar)>,
    scalars: Vec<(String, Scalar)>,
    seed: u64,
    dac_v: f64,
    force_n: f64,
    built: Option<Built>,
}

/// The stage once initialised.
struct Built {
    sim: Simulator,
    period_s: f64,
    plant_sha256: String,
    sample: Sensor,
    tool_m: f64,
}

impl StageUnit {
    /// The stage of `plant` with noise seed `seed`, parameters at those values.
    pub fn new(plant: PlantParams, seed: u64) -> Self {
        let scalars = plant_parameters(&plant);
        StageUnit {
            vars: stage_variables(&plant, seed),
            base: plant,
            start_seed: seed,
            start_scalars: scalars.clone(),
            scalars,
            seed,
            dac_v: 0.0,
            force_n: 0.0,
            built: None,
        }
    }

    fn plant(&self) -> Result<PlantParams, String> {
        plant_with(&self.base, &self.scalars)
    }

    fn built(&mut self) -> Result<&mut Built, String> {
        if self.built.is_none() {
            self.initialize()?;
        }
        Ok(self.built.as_mut().expect("built above"))
    }
}

/// A simulator error with the parameter's full key.
fn plant_error(e: SimError) -> String {
    match e {
        SimError::Model(ModelError::Parameter { key, value, range }) => {
            format!("plant.{key} = {value} is outside its allowed range {range}")
        }
        other => format!("plant: {other}"),
    }
}

impl Model for StageUnit {
    fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn set(&mut self, vr: u32, value: Value) -> Result<(), String> {
        match (vr, value) {
            (stage::DAC_V, Value::Real(x)) => self.dac_v = x,
            (stage::FORCE_N, Value::Real(x)) => self.force_n = x,
            (stage::SEED, Value::Integer(n)) => {
                self.seed = n as u64;
                self.built = None;
            }
            (vr, value) => {
                let i = vr
                    .checked_sub(stage::FIRST_PLANT_PARAMETER)
                    .and_then(|i| self.scalars.get_mut(i as usize))
                    .ok_or_else(|| format!("value reference {vr} is not settable"))?;
                i.1 = match value {
                    Value::Real(x) => Scalar::Real(x),
                    Value::Integer(n) => Scalar::Integer(n.into()),
                    Value::Boolean(b) => Scalar::Boolean(b),
                    Value::String(_) => return Err(format!("{} is not a string", i.0)),
                };
                self.built = None;
            }
        }
        Ok(())
    }

    fn get(&mut self, vr: u32) -> Result<Value, String> {
        Ok(match vr {
            stage::DAC_V => Value::Real(self.dac_v),
            stage::FORCE_N => Value::Real(self.force_n),
            stage::SEED => Value::Integer(self.seed as i32),
            stage::GAP_V => Value::Real(self.built()?.sample.gap_v),
            stage::ACCEL_V => Value::Real(self.built()?.sample.accel_v),
            stage::FLAGS => Value::Integer(self.built()?.sample.flags as i32),
            stage::TOOL_POSITION_M => Value::Real(self.built()?.tool_m),
            stage::PLANT_SHA256 => Value::String(self.built()?.plant_sha256.clone()),
            vr => {
                let (_, scalar) = vr
                    .checked_sub(stage::FIRST_PLANT_PARAMETER)
                    .and_then(|i| self.scalars.get(i as usize))
                    .ok_or_else(|| format!("value reference {vr} is not a variable"))?;
                match *scalar {
                    Scalar::Real(x) => Value::Real(x),
                    Scalar::Integer(n) => Value::Integer(n as i32),
                    Scalar::Boolean(b) => Value::Boolean(b),
                }
            }
        })
    }

    fn initialize(&mut self) -> Result<(), String> {
        if self.built.is_some() {
            return Ok(());
        }
        let plant = self.plant()?;
        let mut sim =
            Simulator::new(&plant, self.seed, &CuttingProfile::None).map_err(plant_error)?;
        let sample = sim.initial();
        self.built = Some(Built {
            sim,
            period_s: plant.period_s(),
            plant_sha256: run_config::made_for_plant(&plant).plant_sha256,
            sample,
            tool_m: 0.0,
        });
        Ok(())
    }

    fn step(&mut self, ticks: u64) -> Result<(), String> {
        let (dac_v, force_n) = (self.dac_v, self.force_n);
        let b = self.built()?;
        for _ in 0..ticks {
            b.sample = b.sim.step_sensor(dac_v, force_n);
        }
        b.tool_m = b.sim.truth().map_or(0.0, |t| t.tool_m);
        Ok(())
    }

    fn period_s(&self) -> f64 {
        if let Some(b) = &self.built {
            return b.period_s;
        }
        match self.plant() {
            Ok(p) => p.period_s(),
            Err(_) => self.base.period_s(),
        }
    }

    fn reset(&mut self) {
        self.scalars.clone_from(&self.start_scalars);
        self.seed = self.start_seed;
        self.dac_v = 0.0;
        self.force_n = 0.0;
        self.built = None;
    }
}
