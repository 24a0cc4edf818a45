//! Controllers loaded into a running loop: parsed, checked and built off the ticking thread,
//! handed over bumplessly at a tick boundary.
//!
//! The check is the deployment's own rule — design work stays offline: a file is taken only
//! if it was made for the loop's plant and rate (`[made_for]`) and carries the offline check of
//! its closed loop (`[stability]`, which `servo synth`, `servo tune` and `servo deploy` write)
//! whose range allows the output scale in force. A host that has the plant model (our own
//! simulated runs) checks with the model instead ([`Vet`]).

use daq_io::ack_status;
use servo_config::Controller;
use servo_config::Invalid;
use servo_config::{parse_controller_file, ConfigError, MadeFor, Origin, LOADED_FILE};
use servo_config::{ControllerSpec, Stability, Stage};
use std::fmt;

/// Why a controller was not taken.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// One of [`ack_status`]: `REFUSED_INVALID`, `REFUSED_PROVENANCE`, `REFUSED_MARGIN`.
    pub status: u32,
    /// The new loop's spectral radius when that was the reason (NaN otherwise).
    pub spectral_radius: f64,
    /// Why, naming the file's key.
    pub message: String,
}

impl Refusal {
    /// A refusal with `status` for `why`.
    pub fn new(status: u32, why: impl fmt::Display) -> Self {
        Refusal {
            status,
            spectral_radius: f64::NAN,
            message: why.to_string(),
        }
    }
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Refusal {}

/// A controller that passed its check: what to build, and the stable range it brings.
#[derive(Debug, Clone, PartialEq)]
pub struct Vetted {
    /// The controller.
    pub spec: ControllerSpec,
    /// Its loop's offline check (the gain range a running loop keeps from now on).
    pub stability: Stability,
}

/// The check a loaded controller file passes before it may run: the bytes of the file in, the
/// controller and its loop's stability out — or why not. Runs off the ticking thread.
pub trait Vet: Send {
    /// Checks `file` (UTF-8 TOML).
    fn vet(&self, file: &[u8]) -> Result<Vetted, Refusal>;
}

/// The deployment's rule ([module docs](self)): provenance and a carried stability record.
pub struct CarriedCheck {
    /// The loop's plant and rate.
    pub made_for: Option<MadeFor>,
    /// The loop's servo rate in Hz.
    pub servo_rate_hz: f64,
    /// The loop's stage (what a file's stability record must have been made on).
    pub stage: Stage,
    /// The controller running now (a state-space file takes its output limit).
    pub running: ControllerSpec,
}

impl Vet for CarriedCheck {
    fn vet(&self, file: &[u8]) -> Result<Vetted, Refusal> {
        let invalid = |e: &dyn fmt::Display| Refusal::new(ack_status::REFUSED_INVALID, e);
        let text = std::str::from_utf8(file)
            .map(|t| t.strip_prefix('\u{feff}').unwrap_or(t))
            .map_err(|e| {
                invalid(&format_args!(
                    "{LOADED_FILE}: not UTF-8 text (invalid byte at offset {})",
                    e.valid_up_to()
                ))
            })?;
        let at = Origin {
            path: Some(LOADED_FILE.into()),
            text: Some(text.to_owned()),
        };
        let f = parse_controller_file(text, &at, &self.running).map_err(|e| invalid(&e))?;
        let (Some(file_for), Some(run)) = (&f.made_for, &self.made_for) else {
            return Err(Refusal::new(
                ack_status::REFUSED_PROVENANCE,
                "the file does not say what it was made for ([made_for]), or this loop does not: a running loop takes only controllers made for its plant",
            ));
        };
        file_for
            .check(run)
            .map_err(|e| Refusal::new(ack_status::REFUSED_PROVENANCE, e))?;
        f.check_rate(self.servo_rate_hz, &at, "the loop's servo rate")
            .map_err(|e| invalid(&e))?;
        let stability = f.stability.ok_or_else(|| {
            Refusal::new(
                ack_status::REFUSED_MARGIN,
                "the file carries no offline check of its loop ([stability]): check it on the plant model first (servo deploy)",
            )
        })?;
        // The record stands for this controller on this loop only if it was made on them.
        let table = match f.sample_rate_hz {
            Some(_) => "stability",
            None => "controller.stability",
        };
        stability
            .check_seal(self.servo_rate_hz, &self.stage, &f.spec)
            .map_err(|e| {
                Refusal::new(ack_status::REFUSED_MARGIN, at.located(&e.in_section(table)))
            })?;
        Ok(Vetted {
            spec: f.spec,
            stability,
        })
    }
}

/// A vetted controller built for the loop (`stage`, `period_s`), boxed to cross threads (and
/// so that the one it replaces is freed off the ticking thread).
pub(crate) fn build(v: &Vetted, stage: &Stage, period_s: f64) -> Result<Box<Controller>, Invalid> {
    servo_config::check_controller(&v.spec, 1.0 / period_s)?;
    Controller::build(&v.spec, stage, period_s).map(Box::new)
}

/// Why [`crate::Servo::load`], [`crate::Loader::prepare`] or [`crate::Servo::swap`] did not
/// take a controller.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LoadError {
    /// The check refused it.
    #[error("{0}")]
    Refused(Refusal),
    /// It passed the check but does not build for this loop.
    #[error("{0}")]
    Invalid(ConfigError),
    /// A controller prepared for another loop (another stage or servo rate).
    #[error("this controller was prepared for another loop (another stage or servo rate): prepare it with this loop's loader")]
    OtherLoop,
    /// A prepared controller already swapped in ([`crate::Servo::swap`] takes each once).
    #[error("this prepared controller was swapped in already: prepare the file again")]
    Spent,
    /// Stable at scale 1, but not at the output scale in force.
    #[error("the new loop is stable only for output scales {low:.4}..={high:.4}; the scale in force is {scale}")]
    Margin {
        /// The scale in force.
        scale: f64,
        /// The lowest scale the new loop allows.
        low: f64,
        /// The highest.
        high: f64,
    },
}
