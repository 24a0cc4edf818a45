//! # plant-sim
//!
//! The fast tool servo stage of the thesis as a deterministic, exactly discretised simulator:
//! four-mass flexure mechanics, FVCM current loop, capacitive sensor, accelerometer, ADC/DAC,
//! transport delay, coloured noise and cutting forces; and the spindle metrology rig of
//! Appendix D (artefact, spindle error motion, probes). See `README.md` for the calibration.
//!
//! The linear model of the tick, for analysis, comes with the `linear` feature (lti's solvers);
//! stepping the stage needs none of it.

// The docs link the linear model's items, which a build without them does not have.
#![cfg_attr(not(feature = "linear"), allow(rustdoc::broken_intra_doc_links))]

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
#[cfg(feature = "linear")]
pub mod quantisation;
#[cfg(feature = "linear")]
pub mod sampled_noise;
pub mod sensor_noise;
pub mod sim;
mod tick_matrix;

pub use model::PlantModel;
pub use params::PlantParams;
#[cfg(feature = "linear")]
pub use sim::LinearTick;
pub use sim::{Simulator, StageMotion};
