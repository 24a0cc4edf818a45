//! # lti
//!
//! The linear-systems numerics that both the simulated stage (`plant-sim`) and the design
//! tools (`design`, `studies`) stand on, with no plotting or optimisation dependencies:
//!
//! | module | what |
//! |---|---|
//! | [`state_space`] | continuous/discrete state space, frequency response, balancing, poles (`solvers`) |
//! | [`discretise`] | `expm`, zero-order hold, the delayed hold of DESIGN.md "Time and delay", Tustin |
//! | [`lyapunov`] | the discrete Lyapunov equation (exact variances of sampled loops) (`solvers`) |
//! | [`riccati`] | continuous and discrete algebraic Riccati equations (`solvers`) |
//! | [`schur_lyapunov`] | Lyapunov and Stein equations by the Schur form (many right-hand sides, one matrix) (`solvers`) |
//! | [`reduce`] | balanced truncation (`solvers`) |
//! | [`level_crossing`] | where a sampled response first falls below a level (bandwidth), found exactly (`solvers`) |
//! | [`square_root`] | the square root of a covariance (exact noise steps, gramian factors) |
//! | [`interconnect`] | named-signal block interconnection (the four-mass stage is built with it) |
//! | [`spectral`] | log grids, exact-bin DFT, Welch PSD, H1 FRF and coherence, CAS |
//! | [`vector_fit`] | a stable rational fit of a sampled system's measured frequency response (z-domain vector fitting) (`solvers`) |
//! | [`welch_statistics`] | what a Welch estimate of a modelled signal should read, and how far it strays by chance (`solvers`) |
//!
//! What is marked (`solvers`) — the eigenvalue, Schur/QZ, Lyapunov and Riccati solvers (faer)
//! and what stands on them — comes with the `solvers` feature. Without it the crate is what a
//! simulated stage needs to step, so libfts_plant links no faer.

// The table above names the solvers' modules, which a build without them does not have.
#![cfg_attr(not(feature = "solvers"), allow(rustdoc::broken_intra_doc_links))]

pub mod discretise;
pub mod frequency_response;
pub mod interconnect;
#[cfg(feature = "solvers")]
pub mod level_crossing;
#[cfg(feature = "solvers")]
pub mod lyapunov;
#[cfg(feature = "solvers")]
pub mod reduce;
#[cfg(feature = "solvers")]
pub mod riccati;
#[cfg(feature = "solvers")]
pub mod schur_lyapunov;
pub mod spectral;
pub mod square_root;
pub mod state_space;
#[cfg(feature = "solvers")]
pub mod vector_fit;
#[cfg(feature = "solvers")]
pub mod welch_statistics;

pub use discretise::{c2d_tustin, expm, zoh, DelayedZoh};
pub use frequency_response::FrequencyResponse;
#[cfg(feature = "solvers")]
pub use lyapunov::dlyap;
pub use square_root::sqrt_factor;
#[cfg(feature = "solvers")]
pub use state_space::eigenvalues;
pub use state_space::{LtiError, StateSpace};
