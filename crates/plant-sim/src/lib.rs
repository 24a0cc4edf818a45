//! # plant-sim
//!
//! The fast tool servo stage of the thesis as a deterministic, exactly discretised simulator:
//! four-mass flexure mechanics, FVCM current loop, capacitive sensor, accelerometer, ADC/DAC,
//! transport delay, coloured noise and cutting forces; and the spindle metrology rig of
//! Appendix D (artefact, spindle error motion, probes). See `README.md` for the calibration.

mod backend;
mod coil_loop;
pub mod convert;
pub mod cutting;
mod gaussian;
pub mod impedance;
pub mod limits;
pub mod metrology;
pub mod model;
pub mod modes;
pub mod params;
pub mod practice;
pub mod quantisation;
pub mod sampled_noise;
pub mod sensor_noise;
pub mod sim;
mod tick_matrix;

pub use model::PlantModel;
pub use params::PlantParams;
pub use sim::{LinearTick, Simulator, StageMotion};
