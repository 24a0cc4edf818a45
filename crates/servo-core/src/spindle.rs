//! Spindle synchronisation (thesis §8.3): the encoder count → spindle angle, a phase-locked
//! tracker that interpolates the angle between encoder pulses and predicts it ahead, and the
//! spiral tool path of facing (X radius falling by the feed per revolution).
//!
//! ```
//! use servo_core::{Block, SpindleTrackerConfig};
//! let cfg = SpindleTrackerConfig { pulses_per_rev: 80_000, speed_rpm: 60.0, bandwidth_hz: 10.0 };
//! let mut pll = cfg.try_build(1.0 / 199_600.0).unwrap();
//! let theta = pll.update(0); // rad, unwrapped
//! assert!(theta.abs() < 1e-4 && !pll.faulted());
//! ```

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};
use core::f64::consts::TAU;

/// A spindle encoder of `pulses_per_rev` (thesis: 80 000): count → angle in rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encoder {
    /// Pulses per revolution.
    pub pulses_per_rev: u64,
}

impl Encoder {
    /// Spindle angle in rad, in [0, 2π), of encoder count `count`.
    #[inline]
    pub fn angle_rad(&self, count: u64) -> f64 {
        let n = self.pulses_per_rev.max(1);
        (count % n) as f64 * (TAU / n as f64)
    }

    /// One pulse in rad.
    #[inline]
    pub fn rad_per_count(&self) -> f64 {
        TAU / self.pulses_per_rev.max(1) as f64
    }

    /// The count the encoder shows at the unwrapped angle `angle_rad` ≥ 0 (pulses since 0).
    #[inline]
    pub fn count_at(&self, angle_rad: f64) -> u64 {
        (angle_rad * (self.pulses_per_rev as f64 / TAU)) as u64
    }
}

/// Configuration of a [`SpindleTracker`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleTrackerConfig {
    /// Encoder pulses per revolution (thesis: 80 000, §8.3).
    pub pulses_per_rev: u64,
    /// Nominal spindle speed in rpm (the tracker's starting rate).
    pub speed_rpm: f64,
    /// Natural frequency of the tracking loop in Hz (ζ = 0.707): lower averages the encoder's
    /// ±½-pulse quantisation more, higher follows speed changes faster.
    pub bandwidth_hz: f64,
}

impl SpindleTrackerConfig {
    /// Validates the configuration for sample period `sample_period_s` (s).
    pub fn try_build(&self, sample_period_s: f64) -> Result<SpindleTracker, Error> {
        let t = check_period(sample_period_s)?;
        check_range("pulses_per_rev", self.pulses_per_rev as f64, 1.0, 1e9)?;
        let rpm = check_range("speed_rpm", self.speed_rpm, -1e6, 1e6)?;
        let wn = TAU * check_range("bandwidth_hz", self.bandwidth_hz, 1e-3, 0.05 / t)? * t;
        let encoder = Encoder {
            pulses_per_rev: self.pulses_per_rev,
        };
        Ok(SpindleTracker {
            rad_per_count: encoder.rad_per_count(),
            period_s: t,
            gain_angle: 2.0 * core::f64::consts::FRAC_1_SQRT_2 * wn,
            gain_rate: wn * wn,
            nominal_rad_s: rpm * TAU / 60.0,
            angle_rad: 0.0,
            rate_rad_s: rpm * TAU / 60.0,
            started: false,
            fault: FaultLatch::default(),
        })
    }
}

/// Pulses of disagreement between the tracker and the encoder at which lock is declared lost.
const LOST_LOCK_PULSES: f64 = 16.0;

/// A second-order (α-β) phase tracker of the spindle angle from the encoder count: estimates
/// the unwrapped angle in rad and the speed in rad/s at every servo tick, between pulses.
/// Losing lock (the count disagrees by 16 pulses: the spindle stalled or the encoder slipped)
/// latches a fault and freezes the angle.
#[derive(Debug, Clone, Copy)]
pub struct SpindleTracker {
    rad_per_count: f64,
    period_s: f64,
    gain_angle: f64,
    gain_rate: f64,
    nominal_rad_s: f64,
    angle_rad: f64,
    rate_rad_s: f64,
    started: bool,
    fault: FaultLatch,
}

impl SpindleTracker {
    /// The angle estimated `ticks` servo periods after the last update, in rad (preview).
    #[inline]
    pub fn predict_rad(&self, ticks: f64) -> f64 {
        self.angle_rad + self.rate_rad_s * ticks * self.period_s
    }

    /// The estimated speed in rad/s.
    pub fn rate_rad_s(&self) -> f64 {
        self.rate_rad_s
    }
}

impl Block for SpindleTracker {
    /// Encoder count (pulses since the start).
    type Input = u64;
    /// Unwrapped spindle angle in rad.
    type Output = f64;

    #[inline]
    fn update(&mut self, count: u64) -> f64 {
        if self.fault.is_set() {
            return self.angle_rad;
        }
        // The count says the angle lies in [count, count + 1) pulses: measure the middle.
        let measured = (count as f64 + 0.5) * self.rad_per_count;
        if !self.started {
            self.started = true;
            self.angle_rad = measured;
            return measured;
        }
        let predicted = self.predict_rad(1.0);
        let e = measured - predicted;
        if libm::fabs(e) > LOST_LOCK_PULSES * self.rad_per_count {
            self.fault.set();
            return self.angle_rad;
        }
        self.angle_rad = predicted + self.gain_angle * e;
        self.rate_rad_s += self.gain_rate * e / self.period_s;
        self.angle_rad
    }

    fn reset(&mut self) {
        self.started = false;
        self.angle_rad = 0.0;
        self.rate_rad_s = self.nominal_rad_s;
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

/// The spiral of facing: the tool starts at `start_radius_m` and moves toward the axis by
/// `feed_m_per_rev` per spindle revolution (thesis Tables 8-4..8-6: 5 µm/rev), stopping at 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spiral {
    /// X radius at spindle angle 0 in m.
    pub start_radius_m: f64,
    /// Radial feed per revolution in m.
    pub feed_m_per_rev: f64,
}

impl Spiral {
    /// X radius in m at the unwrapped spindle angle `theta_rad`.
    #[inline]
    pub fn radius_m(&self, theta_rad: f64) -> f64 {
        (self.start_radius_m - self.feed_m_per_rev * theta_rad / TAU).max(0.0)
    }
}
