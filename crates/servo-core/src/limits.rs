//! Output limits shared by every block that drives an actuator.

use crate::error::{check_range, Error};

/// Closed output interval `[min, max]` in the block's output unit (V for the DAC path).
///
/// ```
/// use servo_core::Limits;
/// let l = Limits::try_new(-10.0, 10.0).unwrap();
/// assert_eq!(l.clamp(12.0), 10.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    min: f64,
    max: f64,
}

impl Limits {
    /// No limit: `[-f64::MAX, f64::MAX]` (outputs stay finite).
    pub const UNLIMITED: Limits = Limits {
        min: -f64::MAX,
        max: f64::MAX,
    };
    /// The ±10 V range of the thesis DAC (§4.4.1).
    pub const DAC_10V: Limits = Limits {
        min: -10.0,
        max: 10.0,
    };

    /// Builds `[min, max]`; infinite bounds are replaced by `∓f64::MAX`.
    pub fn try_new(min: f64, max: f64) -> Result<Self, Error> {
        if min.is_nan() {
            return Err(Error::NotFinite { param: "min" });
        }
        if max.is_nan() {
            return Err(Error::NotFinite { param: "max" });
        }
        let (min, max) = (min.max(-f64::MAX), max.min(f64::MAX));
        if min > max {
            return Err(Error::InvalidLimits { min, max });
        }
        check_range("min", min, -f64::MAX, f64::MAX)?;
        Ok(Limits { min, max })
    }

    /// Lower limit.
    pub fn min(&self) -> f64 {
        self.min
    }

    /// Upper limit.
    pub fn max(&self) -> f64 {
        self.max
    }

    /// `x` clamped into the interval (NaN is not expected here: blocks catch it first).
    #[inline]
    pub fn clamp(&self, x: f64) -> f64 {
        x.clamp(self.min, self.max)
    }

    /// Whether `x` lies strictly outside the interval.
    #[inline]
    pub fn saturates(&self, x: f64) -> bool {
        x > self.max || x < self.min
    }
}

impl Default for Limits {
    fn default() -> Self {
        Limits::UNLIMITED
    }
}
