//! # lti
//!
//! The linear-systems numerics that both the simulated stage (`plant-sim`) and the design
//! tools (`design`, `studies`) stand on, with no plotting or optimisation dependencies:
//!
//! | module | what |
//! |---|---|
//! | [`state_space`] | continuous/discrete state space, frequency response, balancing, poles |
//! | [`discretise`] | `expm`, zero-order hold, the delayed hold of DESIGN.md "Time and delay", Tustin |
//! | [`lyapunov`] | the discrete Lyapunov equation (exact variances of sampled loops) |
//! | [`riccati`] | continuous and discrete algebraic Riccati equations |
//! | [`schur_lyapunov`] | Lyapunov and Stein equations by the Schur form (many right-hand sides, one matrix) |
//! | [`reduce`] | balanced truncation |
//! | [`level_crossing`] | where a sampled response first falls below a level (bandwidth), found exactly |
//! | [`interconnect`] | named-signal block interconnection (the four-mass stage is built with it) |
//! | [`spectral`] | log grids, exact-bin DFT, Welch PSD, H1 FRF and coherence, CAS |
//! | [`vector_fit`] | a stable rational fit of a sampled system's measured frequency response (z-domain vector fitting) |
//! | [`welch_statistics`] | what a Welch estimate of a modelled signal should read, and how far it strays by chance |

pub mod discretise;
pub mod frequency_response;
pub mod interconnect;
pub mod level_crossing;
pub mod lyapunov;
pub mod reduce;
pub mod riccati;
pub mod schur_lyapunov;
pub mod spectral;
pub mod state_space;
pub mod vector_fit;
pub mod welch_statistics;

pub use discretise::{c2d_tustin, expm, zoh, DelayedZoh};
pub use frequency_response::FrequencyResponse;
pub use lyapunov::dlyap;
pub use reduce::sqrt_factor;
pub use state_space::{eigenvalues, LtiError, StateSpace};
