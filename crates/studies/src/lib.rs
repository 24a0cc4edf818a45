//! # studies
//!
//! The offline studies of fts-servo, each on a resolved [`runner::Plan`] and each owning its
//! report (JSON/CSV data, PNG/SVG plots):
//!
//! | module | thesis | what |
//! |---|---|---|
//! | [`budget`] | §5.7.2, Fig 5-15/5-16 | per-source error budget, PSD and CAS |
//! | [`sweep`] | §5.7.3, Fig 5-14 | RMS errors against closed-loop bandwidth |
//! | [`margins`] | | gain and phase margins at the actuator |
//! | [`frf`] | §5.5.1, §5.7.5 | stepped-sine / chirp FRF on the running simulator beside the model |
//! | [`identify`] | §5.5.3 | Table 5-2 parameters fitted to an open-loop FRF |
//! | [`fit`] | | a rational model of a measured FRF, and the modes the plant model lacks |
//! | [`stiffness`] | eq 7-9, Table 7-1 | dynamic compliance with acceleration feedback |
//! | [`intermittent`] | §7.6 | the intermittent cut per acceleration gain |
//! | [`synth`] | Ch. 6 | H2-optimal controller files |
//! | [`tune`] | Ch. 7 | PID tuning under Ms, Mt and a bandwidth |
//! | [`form`] | Ch. 8 | machined form error, grid amplitude, trajectory |
//! | [`spectrum`] | §5.7.4, Fig 5-15/5-16 | PSD and CAS of a recording beside the budget's prediction |
//! | [`spindle`] | Appendix D | three-probe spindle error separation |
//! | [`toolpath`] | §9.3.1 | a prescription's tool path: demands per band, predicted form error, sensitivities |
//! | [`design_space`] | §6.5, Fig 6-13…6-18 | structural design studies: grids and samples over plant parameters |

pub mod budget;
pub mod design_space;
mod error;
pub mod fit;
pub mod form;
pub mod frf;
pub mod identify;
pub mod intermittent;
pub mod margins;
pub mod measured;
pub mod report;
pub mod spectrum;
pub mod spindle;
pub mod stiffness;
pub mod sweep;
pub mod synth;
pub mod thesis;
pub mod toolpath;
pub mod tune;

pub use error::StudyError;
