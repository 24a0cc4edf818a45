//! # servo-config
//!
//! What a fast-tool-servo loop is made of, as data: the [`Deployment`] (the stage's numbers the
//! tick uses, the controller, its checked gain range, the reference, the feedforward and
//! machine protection), the range check of every value ([`Invalid`] names its key), the
//! stability record's seal, the controller law a specification builds ([`Controller`]), the
//! reference path's frequency response, and — with the standard library — the TOML files
//! `servo deploy`, `servo synth` and `servo tune` write and the runtime reads.
//!
//! The embedder's crate is `servo-runtime`: it re-exports the deployment's types and keeps
//! everything else here, for the workspace's own tools (the run planner, the studies, the
//! processor-in-the-loop link). Without default features the crate is `#![no_std]` with no
//! allocator.
#![cfg_attr(not(feature = "std"), no_std)]

mod check;
mod controller;
mod deployment;
mod protection;
mod reference_path;
mod seal;
mod validate;

#[cfg(feature = "std")]
mod file;

pub use check::{Allowed, Invalid};
pub use controller::{accel_shaping, kg_of, position_pid, Controller};
pub use deployment::{
    ControllerKind, ControllerSpec, Deployment, FeedforwardSpec, FirSpec, PidGains, ReferenceSpec,
    Seal, SsMatrices, Stability, Stage, ZpetcSpec, GAIN_MARGIN, MAX_FIR_SPAN, MAX_FIR_TAPS,
    MAX_PREVIEW, MAX_SS_ORDER, ZPETC_SECTIONS,
};
pub use protection::{ProtectionConfig, SafeState};
pub use reference_path::{hann_weights, reference_path, Complex, PathResponse};
pub use validate::{check_controller, check_reference};

#[cfg(feature = "std")]
pub use file::{
    controller_toml, deployment_toml, exact_array, exact_arrays, line_of, matrix, num,
    parse_controller_file, parse_deployment, read_input, read_text, stability_toml, toml_message,
    ConfigError, ControllerFile, DeploymentAndProvenance, MadeFor, Mismatch, Origin, LOADED_FILE,
    MAX_IMAGE_BYTES, MAX_TEXT_BYTES,
};
