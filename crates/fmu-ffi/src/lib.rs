//! # libfts_fmu
//!
//! The FMI 2.0 and 3.0 co-simulation functions of fts-servo's units: the simulated stage and
//! the controller of a deployment. `servo fmu` packs this one library into each `.fmu`
//! archive under the unit's model identifier; at instantiation it reads the archive's
//! `resources/unit.toml` (which unit, its configuration), checks it against the description's
//! instantiation token and serves the variables the description lists (crate `fmu`).
//!
//! A unit steps whole servo ticks: a communication step that is not a whole number of ticks
//! (within [`instance::TICK_TOLERANCE`] of one) is refused with an error, never interpolated.

mod boundary;
mod controller;
pub mod fmi2;
pub mod fmi3;
pub mod instance;
mod model;
mod stage;
