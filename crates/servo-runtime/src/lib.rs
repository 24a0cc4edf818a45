//! # servo-runtime
//!
//! The fast-tool-servo controller a lab embeds in its own real-time loop — a C/C++ or Rust DAQ
//! daemon, a machine controller's servo thread, a microcontroller. Everything that runs per
//! tick: the reference with its preview and smoothing, the feedforward, the feedback controller
//! (PID, state space up to [`deployment::MAX_SS_ORDER`] = 40, the acceleration cascade), machine protection
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
//! - [`Deployment`] and its parts ([`deployment`]), [`Invalid`] (a value out of range, named
//!   by its key, with what is [`Allowed`]), [`ConfigError`] (the same located in a file),
//!   [`Status`], [`Trip`], [`TripCause`], [`GainRefused`], [`Timing`].
//! - Loading a controller while running: [`Servo::load`], or in two phases off the ticking
//!   thread ([`Servo::loader`] → [`Loader::prepare`] → [`Servo::swap`] with a [`Prepared`]);
//!   [`LoadError`]. A host with its own check of a loaded file implements [`Vet`] ([`Vetted`],
//!   [`Refusal`]) and passes it in [`ServeOptions`].
//!
//! The whole public surface is listed in `public-api.txt` beside this crate's manifest (a test
//! keeps the listing true). The configuration plumbing our own tools share (TOML helpers, the
//! controller law alone, the reference path's response) is in the `servo-config` crate.
//!
//! ## Features
//! - default `std`: deployments and controller files from TOML, loads, tick timing.
//! - `serve`: telemetry, health and the control plane over iceoryx2 from a thread of its own.
//! - without default features the crate is `#![no_std]` with no allocator: [`Servo::new`],
//!   [`Servo::tick`] and the rest of the per-tick core, for a microcontroller.
#![cfg_attr(not(feature = "std"), no_std)]

mod feedforward;
mod fir;
mod preview;
mod protection;
mod reference;
mod servo;
mod servo_loop;
mod status;

#[cfg(feature = "std")]
mod host;
#[cfg(feature = "std")]
mod load;
#[cfg(feature = "std")]
mod prepared;
#[cfg(feature = "serve")]
mod serve;

/// The parts of a [`Deployment`]: every number of the loop, in SI units, checked by
/// [`Deployment::check`] (see each type for its keys and ranges).
pub mod deployment {
    pub use servo_config::{
        ControllerKind, ControllerSpec, FeedforwardSpec, FirSpec, PidGains, ProtectionConfig,
        ReferenceSpec, SafeState, Seal, SsMatrices, Stability, Stage, ZpetcSpec, GAIN_MARGIN,
        MAX_FIR_TAPS, MAX_PREVIEW, MAX_SS_ORDER, ZPETC_SECTIONS,
    };
    #[cfg(feature = "std")]
    pub use servo_config::{MadeFor, Mismatch};
}

pub use protection::TripCause;
pub use reference::Reference;
pub use servo::Servo;
pub use servo_config::{Allowed, Deployment, Invalid};
pub use status::{GainRefused, Status, Trip};

#[cfg(feature = "std")]
pub use host::Timing;
#[cfg(feature = "std")]
pub use load::{LoadError, Refusal, Vet, Vetted};
#[cfg(feature = "std")]
pub use prepared::{Loader, Prepared};
#[cfg(feature = "serve")]
pub use serve::{ServeError, ServeOptions};
#[cfg(feature = "std")]
pub use servo_config::ConfigError;

// Paths the crate's modules use as `crate::…`.
#[cfg(feature = "std")]
use load::CarriedCheck;
#[cfg(feature = "std")]
use servo_config::{parse_deployment, read_text, Origin};
