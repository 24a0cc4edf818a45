//! Delay lines: an integer-sample delay, a first-order Thiran all-pass fractional delay, and
//! the two in series modelling a transport delay that is not a multiple of the sample period
//! (the 3.159 µs of thesis Table 4-2 is 0.63 samples at 199.6 kHz).

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};

/// `y[k] = x[k − n]` for a run-time `n ≤ CAP` samples.
///
/// ```
/// use servo_core::{Block, IntegerDelay};
/// let mut d = IntegerDelay::<4>::try_new(2).unwrap();
/// assert_eq!([d.update(1.0), d.update(2.0), d.update(3.0)], [0.0, 0.0, 1.0]);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct IntegerDelay<const CAP: usize> {
    buf: [f64; CAP],
    len: usize,
    head: usize,
    fault: FaultLatch,
}

impl<const CAP: usize> IntegerDelay<CAP> {
    /// A delay of `samples` (0 passes the input through).
    pub fn try_new(samples: usize) -> Result<Self, Error> {
        if samples > CAP {
            return Err(Error::DelayTooLong {
                samples,
                capacity: CAP,
            });
        }
        Ok(IntegerDelay {
            buf: [0.0; CAP],
            len: samples,
            head: 0,
            fault: FaultLatch::default(),
        })
    }

    /// The delay in samples.
    pub fn samples(&self) -> usize {
        self.len
    }
}

impl<const CAP: usize> Block for IntegerDelay<CAP> {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: f64) -> f64 {
        let y = if self.len == 0 {
            x
        } else {
            let y = core::mem::replace(&mut self.buf[self.head], x);
            self.head = if self.head + 1 == self.len {
                0
            } else {
                self.head + 1
            };
            y
        };
        // The input is checked too: a NaN must fault now, not `n` ticks later.
        if self.fault.check(x + y) {
            return 0.0;
        }
        y
    }

    fn reset(&mut self) {
        self.buf = [0.0; CAP];
        self.head = 0;
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

/// First-order Thiran all-pass `H(z) = (η + z⁻¹)/(1 + η z⁻¹)`, `η = (1 − D)/(1 + D)`: unit
/// magnitude at every frequency and group delay exactly `D` samples at DC (maximally flat).
/// Stable for `D > 0`; most accurate for `D` in `[0.5, 1.5]`.
///
/// ```
/// use servo_core::ThiranDelay;
/// let d = ThiranDelay::try_new(0.63).unwrap();
/// assert!((d.dc_group_delay() - 0.63).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct ThiranDelay {
    eta: f64,
    x_prev: f64,
    y_prev: f64,
    fault: FaultLatch,
}

impl ThiranDelay {
    /// A fractional delay of `samples` ∈ (0, 100].
    pub fn try_new(samples: f64) -> Result<Self, Error> {
        let d = check_range("delay_samples", samples, 1e-9, 100.0)?;
        Ok(ThiranDelay {
            eta: (1.0 - d) / (1.0 + d),
            x_prev: 0.0,
            y_prev: 0.0,
            fault: FaultLatch::default(),
        })
    }

    /// Group delay at DC in samples, `(1 − η)/(1 + η)`.
    pub fn dc_group_delay(&self) -> f64 {
        (1.0 - self.eta) / (1.0 + self.eta)
    }
}

impl Block for ThiranDelay {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: f64) -> f64 {
        let y = self.eta * (x - self.y_prev) + self.x_prev;
        self.x_prev = x;
        self.y_prev = crate::math::flush(y);
        if self.fault.check(y) {
            return 0.0;
        }
        y
    }

    fn reset(&mut self) {
        self.x_prev = 0.0;
        self.y_prev = 0.0;
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

/// A transport delay `delay_s` split into whole samples and a Thiran fraction in `[0.5, 1.5)`
/// (or all-fractional below 0.5 samples; exactly zero passes through).
///
/// ```
/// use servo_core::TransportDelay;
/// // Thesis Table 4-2: 3.159 µs at the 199.6 kHz servo rate.
/// let d = TransportDelay::<8>::try_new(3.159e-6, 1.0 / 199_600.0).unwrap();
/// assert!((d.delay_samples() - 3.159e-6 * 199_600.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct TransportDelay<const CAP: usize> {
    whole: IntegerDelay<CAP>,
    fraction: Option<ThiranDelay>,
}

impl<const CAP: usize> TransportDelay<CAP> {
    /// A delay of `delay_s` (s) at `sample_period_s` (s).
    pub fn try_new(delay_s: f64, sample_period_s: f64) -> Result<Self, Error> {
        let t = check_period(sample_period_s)?;
        let d = check_range("delay_s", delay_s, 0.0, (CAP as f64 + 1.5) * t)? / t;
        let (whole, fraction) = if d == 0.0 {
            (0, None)
        } else if d < 0.5 {
            (0, Some(d))
        } else {
            let whole = libm::floor(d - 0.5);
            (whole as usize, Some(d - whole))
        };
        Ok(TransportDelay {
            whole: IntegerDelay::try_new(whole)?,
            fraction: fraction.map(ThiranDelay::try_new).transpose()?,
        })
    }

    /// Total DC delay in samples.
    pub fn delay_samples(&self) -> f64 {
        self.whole.samples() as f64 + self.fraction.map_or(0.0, |f| f.dc_group_delay())
    }
}

impl<const CAP: usize> Block for TransportDelay<CAP> {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: f64) -> f64 {
        let y = self.whole.update(x);
        let y = match &mut self.fraction {
            Some(f) => f.update(y),
            None => y,
        };
        if self.faulted() {
            return 0.0;
        }
        y
    }

    fn reset(&mut self) {
        self.whole.reset();
        if let Some(f) = &mut self.fraction {
            f.reset();
        }
    }

    fn faulted(&self) -> bool {
        self.whole.faulted() || self.fraction.is_some_and(|f| f.faulted())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integer_delay_is_exact_on_impulses() {
        for n in 0..=16 {
            let mut d = IntegerDelay::<16>::try_new(n).unwrap();
            for k in 0..64 {
                let x = if k % 20 == 0 { 1.0 } else { 0.0 };
                let expected = if k >= n && (k - n) % 20 == 0 {
                    1.0
                } else {
                    0.0
                };
                assert_eq!(d.update(x), expected, "n={n} k={k}");
            }
        }
        assert_eq!(
            IntegerDelay::<4>::try_new(5).unwrap_err(),
            Error::DelayTooLong {
                samples: 5,
                capacity: 4
            }
        );
    }

    /// The impulse response's first moment Σk·h[k] / Σh[k] is the DC group delay; measured on
    /// the running filter it must be within 1 % of the request.
    #[test]
    fn fractional_group_delay_at_dc_within_one_percent() {
        for &(delay_s, rate) in &[
            (3.159e-6, 199_600.0),
            (3.5e-6, 199_600.0),
            (3.159e-6, 20_000.0),
            (12.0e-6, 199_600.0),
        ] {
            let mut d = TransportDelay::<8>::try_new(delay_s, 1.0 / rate).unwrap();
            let (mut m0, mut m1) = (0.0, 0.0);
            for k in 0..200_000 {
                let h = d.update(if k == 0 { 1.0 } else { 0.0 });
                m0 += h;
                m1 += k as f64 * h;
            }
            let measured = m1 / m0;
            let requested = delay_s * rate;
            assert!((m0 - 1.0).abs() < 1e-9, "DC gain {m0}");
            assert!(
                (measured - requested).abs() < 0.01 * requested,
                "{measured} vs {requested}"
            );
        }
    }

    #[test]
    fn thiran_is_all_pass() {
        // A sine keeps its amplitude: steady-state RMS over whole periods equals 1/√2.
        let mut d = ThiranDelay::try_new(0.63).unwrap();
        let w = 2.0 * core::f64::consts::PI / 40.0;
        let mut sum = 0.0;
        for k in 0..40_000 {
            let y = d.update(libm::sin(w * k as f64));
            if k >= 20_000 {
                sum += y * y;
            }
        }
        assert!((sum / 20_000.0 - 0.5).abs() < 1e-9);
    }
}
