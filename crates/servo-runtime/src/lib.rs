//! # servo-runtime
//!
//! The fast-tool-servo controller a lab embeds in its own real-time loop — a C/C++ or Rust DAQ
//! daemon, a machine controller's servo thread, a microcontroller. Everything that runs per
//! tick: the reference with its preview and smoothing, the feedforward, the feedback controller
//! (PID, state space up to [`MAX_SS_ORDER`] = 40, the acceleration cascade), machine protection
//! and its safe states, bumpless controller swap, output-scale changes checked against the
//! loop's stored stability range, tick statistics — behind one front door, [`Servo`].
//!
//! Design work — ZPETC and H2 design, PID tuning, the stability check against the plant model
//! — is done offline (`servo deploy`, `servo synth`, `servo tune`) and handed to the runtime as
//! coefficients and checked ranges in a [`Deployment`], which says what it was made for.
//!
//! ```no_run
//! use servo_runtime::Servo;
//! # fn adc() -> daq_io::Sensor { Default::default() }
//! # fn dac(_: f64) {}
//! let mut servo = Servo::from_file("deploy.toml")?; // written by `servo deploy`
//! # #[cfg(feature = "serve")]
//! servo.serve("lab")?; // optional (feature `serve`): servo record / ctl / view / the Python tap
//! while servo.status().stop.is_none() {
//!     let sample = adc(); // the gap and accelerometer readings, in V
//!     let command = servo.tick(&sample); // no allocation, lock, log or panic
//!     dac(command.dac_v);
//! }
//! # #[cfg(feature = "serve")]
//! servo.close(0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! ## The stable API
//! - [`Servo`]: [`Servo::new`] (from a [`Deployment`]), [`Servo::from_file`] and
//!   [`Servo::from_toml`] (the TOML `servo deploy` writes), [`Servo::tick`] and
//!   [`Servo::tick_with`] (a host's own [`Reference`]), [`Servo::telemetry`],
//!   [`Servo::status`], [`Servo::set_gain`], [`Servo::reset`], [`Servo::load`],
//!   [`Servo::timing`]; with feature `serve`, [`Servo::serve`], [`Servo::serve_with`] and
//!   [`Servo::close`].
//! - [`Deployment`] and its parts, [`Invalid`] (a value out of range, named by its key),
//!   [`ConfigError`] (the same located in a file), [`TripCause`].
//!
//! ## Features
//! - default `std`: deployments and controller files from TOML, loads, tick timing.
//! - `serve`: telemetry, health and the control plane over iceoryx2 from a thread of its own.
//! - without default features the crate is `#![no_std]` with no allocator: [`Servo::new`],
//!   [`Servo::tick`] and the rest of the per-tick core, for a microcontroller.
#![cfg_attr(not(feature = "std"), no_std)]

mod check;
mod controller;
mod deployment;
mod feedforward;
pub mod link;
mod preview;
mod protection;
mod reference;
mod reference_path;
mod seal;
mod servo;
mod servo_loop;
mod status;
mod validate;

#[cfg(feature = "std")]
mod file;
#[cfg(feature = "std")]
mod host;
#[cfg(feature = "std")]
mod load;
#[cfg(feature = "std")]
mod prepared;
#[cfg(feature = "serve")]
mod serve;

pub use check::{Allowed, Invalid};
pub use controller::{accel_shaping, kg_of, position_pid, Controller};
pub use deployment::{
    ControllerKind, ControllerSpec, Deployment, FeedforwardSpec, PidGains, ProtectionConfig,
    ReferenceSpec, SafeState, Seal, SsMatrices, Stability, Stage, ZpetcSpec, GAIN_MARGIN,
    MAX_PREVIEW, MAX_SS_ORDER, ZPETC_SECTIONS,
};
pub use protection::TripCause;
pub use reference::Reference;
pub use reference_path::{Complex, PathResponse};
pub use servo::Servo;
pub use servo_loop::HANDOVER_TIME_CONSTANT_S;
pub use status::{GainRefused, Status, Trip};
pub use validate::{check_controller, check_reference};

#[cfg(feature = "std")]
pub use file::{
    controller_toml, deployment_toml, exact_array, exact_arrays, line_of, matrix, num,
    parse_controller_file, parse_deployment, read_input, read_text, stability_toml, toml_message,
    ConfigError, ControllerFile, DeploymentAndProvenance, MadeFor, Mismatch, Origin,
    MAX_IMAGE_BYTES, MAX_TEXT_BYTES,
};
#[cfg(feature = "std")]
pub use host::Timing;
#[cfg(feature = "std")]
pub use load::{CarriedCheck, LoadError, Refusal, Vet, Vetted, LOADED_FILE};
#[cfg(feature = "std")]
pub use prepared::{Loader, Prepared};
#[cfg(feature = "serve")]
pub use serve::{ServeError, ServeOptions, SERVICE_TICKS};
