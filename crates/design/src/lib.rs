//! # design
//!
//! Offline design and analysis for fts-servo: continuous LTI models, frequency responses,
//! exact (delayed) zero-order-hold discretisation, and spectral estimation.

pub mod h2;
pub mod identify;
pub mod interconnect;
pub mod loops;
mod lp;
pub mod lti;
pub mod plot;
pub mod reduce;
pub mod riccati;
pub mod spectral;
pub mod spindle;
pub mod tune;
pub mod zpetc;
