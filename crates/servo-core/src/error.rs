//! Configuration errors returned by the `try_build` constructors.
//!
//! The servo tick never returns an error: it clamps and latches faults. Only building
//! coefficients from a configuration can fail, and the error carries what is needed to act.

use core::fmt;

/// Why a block configuration was rejected.
///
/// ```
/// use servo_core::{Error, PidConfig};
/// let err = PidConfig { tf_s: -1.0, ..PidConfig::THESIS_CH7 }.try_build(5e-6).unwrap_err();
/// assert!(matches!(err, Error::OutOfRange { param: "tf_s", .. }));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Error {
    /// A parameter is NaN or infinite.
    NotFinite {
        /// Name of the configuration field.
        param: &'static str,
    },
    /// A parameter lies outside its allowed closed interval `[min, max]`.
    OutOfRange {
        /// Name of the configuration field.
        param: &'static str,
        /// The offending value (in the field's unit).
        value: f64,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
    },
    /// Lower limit above upper limit.
    InvalidLimits {
        /// Configured lower limit.
        min: f64,
        /// Configured upper limit.
        max: f64,
    },
    /// A delay needs more samples than the block's const-generic capacity.
    DelayTooLong {
        /// Requested delay in samples.
        samples: usize,
        /// Capacity of the delay line in samples.
        capacity: usize,
    },
}

impl Error {
    /// The kind of error, for generic code that reacts without matching on data.
    pub fn kind(&self) -> ErrorKind {
        match self {
            Error::NotFinite { .. } | Error::OutOfRange { .. } | Error::InvalidLimits { .. } => {
                ErrorKind::InvalidParameter
            }
            Error::DelayTooLong { .. } => ErrorKind::Capacity,
        }
    }
}

/// Coarse classification of [`Error`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A configuration value is not allowed.
    InvalidParameter,
    /// A const-generic capacity is too small for the configuration.
    Capacity,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NotFinite { param } => write!(f, "`{param}` must be a finite number"),
            Error::OutOfRange {
                param,
                value,
                min,
                max,
            } => write!(
                f,
                "`{param}` = {value} is outside the allowed range [{min}, {max}]"
            ),
            Error::InvalidLimits { min, max } => {
                write!(
                    f,
                    "output limits [{min}, {max}]: the lower limit exceeds the upper"
                )
            }
            Error::DelayTooLong { samples, capacity } => write!(
                f,
                "a delay of {samples} samples exceeds the delay line capacity of {capacity}"
            ),
        }
    }
}

impl core::error::Error for Error {}

/// Checks that `value` is finite and in `[min, max]`; returns it unchanged.
pub(crate) fn check_range(
    param: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, Error> {
    if !value.is_finite() {
        return Err(Error::NotFinite { param });
    }
    if value < min || value > max {
        return Err(Error::OutOfRange {
            param,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// Checks a finite, strictly positive sample period in seconds.
pub(crate) fn check_period(sample_period_s: f64) -> Result<f64, Error> {
    check_range("sample_period_s", sample_period_s, f64::MIN_POSITIVE, 1.0e3)
}
