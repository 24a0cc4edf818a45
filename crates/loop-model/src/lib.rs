//! # loop-model
//!
//! A run's closed loop as linear models, for the analyses that never tick: the controller's
//! realisation ([`controller`]), the exact sampled loop of the simulated stage and that
//! controller — stability, frequency responses, bandwidth ([`closed_loop`]) — the same loop
//! closed on a measured FRF of the stage with its uncertainty ([`measured_loop`]), and the
//! feedforward designed on either ([`feedforward`]: ZPETC on the model, an FIR fitted to the
//! measurement). The run planner (`runner`) checks every run on these before it ticks; the
//! studies build their budgets, sweeps and margins on them.

pub mod closed_loop;
pub mod controller;
pub mod feedforward;
pub mod measured_loop;
