//! Helpers shared by the plant-sim integration tests.
#![allow(dead_code, missing_docs)]

use plant_sim::params::{NoiseParams, PlantParams};

/// `p` with every noise source off and ideal converters: a deterministic, linear plant.
pub fn quiet_ideal(mut p: PlantParams) -> PlantParams {
    p.noise = NoiseParams {
        sensor: false,
        current: false,
        base: false,
        accel: false,
        ..p.noise
    };
    p.adc.bits = 0;
    p.dac.bits = 0;
    p
}
