//! Setpoint generators: step, sine, chirp and the stepped-sine sweep of thesis §5.5.1.
//!
//! Each is a [`Block`] with input `()` that yields a [`Setpoint`] per tick: the position and its
//! analytic first and second time derivatives (for feedforward). Time is `k·T` from the tick
//! count, so long runs do not accumulate rounding. Units are the amplitude's (usually m, or V of
//! sensor signal), per s and per s².

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};
use core::f64::consts::PI;

/// A reference sample: position and its time derivatives.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Setpoint {
    /// Position (amplitude unit).
    pub position: f64,
    /// First derivative (unit/s).
    pub velocity: f64,
    /// Second derivative (unit/s²).
    pub acceleration: f64,
}

impl Setpoint {
    /// Everything zero: hold position at the origin.
    pub const ZERO: Setpoint = Setpoint {
        position: 0.0,
        velocity: 0.0,
        acceleration: 0.0,
    };

    /// `a·sin φ(t)` with phase rate `dphi` (rad/s) and phase acceleration `ddphi` (rad/s²),
    /// and an envelope `(a, da, dda)`: its value, slope (unit/s) and curvature (unit/s²).
    fn sine(phi: f64, dphi: f64, ddphi: f64, (a, da, dda): (f64, f64, f64)) -> Setpoint {
        let (s, c) = (libm::sin(phi), libm::cos(phi));
        Setpoint {
            position: a * s,
            velocity: da * s + a * dphi * c,
            acceleration: dda * s + 2.0 * da * dphi * c + a * (ddphi * c - dphi * dphi * s),
        }
    }
}

/// Tick counter shared by the generators.
#[derive(Debug, Clone, Copy)]
struct Clock {
    k: u64,
    period_s: f64,
    fault: FaultLatch,
}

impl Clock {
    fn try_new(sample_period_s: f64) -> Result<Self, Error> {
        Ok(Clock {
            k: 0,
            period_s: check_period(sample_period_s)?,
            fault: FaultLatch::default(),
        })
    }

    /// The time of the current tick in s, then advances.
    fn tick(&mut self) -> f64 {
        let t = self.k as f64 * self.period_s;
        self.k += 1;
        t
    }

    /// Passes `s` through unless it is not finite (then zero and a latched fault).
    fn guard(&mut self, s: Setpoint) -> Setpoint {
        if self.fault.check(s.position + s.velocity + s.acceleration) {
            Setpoint::ZERO
        } else {
            s
        }
    }

    fn reset(&mut self) {
        self.k = 0;
        self.fault = FaultLatch::default();
    }
}

macro_rules! generator_block {
    ($ty:ty, $self:ident, $t:ident => $body:expr) => {
        impl $ty {
            /// Makes the next update give the value of tick `tick` (forward or back, in
            /// constant time: the value is a closed form of the tick's time), so a loop that
            /// skipped samples stays on the plant's time.
            #[inline]
            pub fn seek(&mut $self, tick: u64) {
                $self.clock.k = tick;
            }
        }

        impl Block for $ty {
            type Input = ();
            type Output = Setpoint;

            #[inline]
            fn update(&mut $self, _: ()) -> Setpoint {
                let $t = $self.clock.tick();
                let s = $body;
                $self.clock.guard(s)
            }

            fn reset(&mut $self) {
                $self.clock.reset();
            }

            fn faulted(&$self) -> bool {
                $self.clock.fault.is_set()
            }
        }
    };
}

/// A step of `amplitude` at `delay_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepConfig {
    /// Step height (unit).
    pub amplitude: f64,
    /// Time of the step in s (`≥ 0`).
    pub delay_s: f64,
}

impl StepConfig {
    /// A step generator ticking every `sample_period_s` s.
    pub fn try_build(&self, sample_period_s: f64) -> Result<Step, Error> {
        Ok(Step {
            amplitude: check_range("amplitude", self.amplitude, -1e9, 1e9)?,
            delay_s: check_range("delay_s", self.delay_s, 0.0, 1e9)?,
            clock: Clock::try_new(sample_period_s)?,
        })
    }
}

/// Step generator (derivatives are zero; the ideal step has no finite derivative).
///
/// ```
/// use servo_core::{Block, StepConfig};
/// let mut s = StepConfig { amplitude: 1e-6, delay_s: 1e-3 }.try_build(1e-3).unwrap();
/// assert_eq!([s.update(()).position, s.update(()).position], [0.0, 1e-6]);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Step {
    amplitude: f64,
    delay_s: f64,
    clock: Clock,
}

generator_block!(Step, self, t => Setpoint {
    position: if t >= self.delay_s { self.amplitude } else { 0.0 },
    ..Setpoint::ZERO
});

/// `offset + amplitude·sin(2π·f·t + phase)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SineConfig {
    /// Amplitude (unit).
    pub amplitude: f64,
    /// Frequency in Hz (below Nyquist).
    pub frequency_hz: f64,
    /// Phase at t = 0 in rad.
    pub phase_rad: f64,
    /// Constant offset (unit).
    pub offset: f64,
}

impl SineConfig {
    /// A sine generator ticking every `sample_period_s` s.
    pub fn try_build(&self, sample_period_s: f64) -> Result<Sine, Error> {
        let clock = Clock::try_new(sample_period_s)?;
        let f = check_range("frequency_hz", self.frequency_hz, 0.0, 0.5 / clock.period_s)?;
        Ok(Sine {
            amplitude: check_range("amplitude", self.amplitude, -1e9, 1e9)?,
            w: 2.0 * PI * f,
            phase: check_range("phase_rad", self.phase_rad, -1e3, 1e3)?,
            offset: check_range("offset", self.offset, -1e9, 1e9)?,
            clock,
        })
    }
}

/// Sine generator.
///
/// ```
/// use servo_core::{Block, SineConfig};
/// let cfg = SineConfig { amplitude: 2.0, frequency_hz: 250.0, phase_rad: 0.0, offset: 0.0 };
/// let mut s = cfg.try_build(1e-3).unwrap();
/// s.update(());
/// assert!((s.update(()).position - 2.0).abs() < 1e-12); // t = 1 ms is a quarter period
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Sine {
    amplitude: f64,
    w: f64,
    phase: f64,
    offset: f64,
    clock: Clock,
}

generator_block!(Sine, self, t => {
    let mut s = Setpoint::sine(
        self.w * t + self.phase,
        self.w,
        0.0,
        (self.amplitude, 0.0, 0.0),
    );
    s.position += self.offset;
    s
});

/// How a chirp's frequency moves from start to end.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sweep {
    /// `f(t) = f0 + (f1 − f0)·t/D`.
    Linear,
    /// `f(t) = f0·(f1/f0)^(t/D)` (equal time per decade).
    Exponential,
}

/// A swept sine from `f_start_hz` to `f_end_hz` over `duration_s`, zero afterwards.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChirpConfig {
    /// Amplitude (unit).
    pub amplitude: f64,
    /// Start frequency in Hz (`> 0`).
    pub f_start_hz: f64,
    /// End frequency in Hz (below Nyquist).
    pub f_end_hz: f64,
    /// Sweep duration in s.
    pub duration_s: f64,
    /// Linear or exponential sweep.
    pub sweep: Sweep,
}

impl ChirpConfig {
    /// A chirp generator ticking every `sample_period_s` s.
    pub fn try_build(&self, sample_period_s: f64) -> Result<Chirp, Error> {
        let clock = Clock::try_new(sample_period_s)?;
        let nyquist = 0.5 / clock.period_s;
        let f0 = check_range("f_start_hz", self.f_start_hz, 1e-6, nyquist)?;
        let f1 = check_range("f_end_hz", self.f_end_hz, 1e-6, nyquist)?;
        let d = check_range("duration_s", self.duration_s, clock.period_s, 1e9)?;
        Ok(Chirp {
            amplitude: check_range("amplitude", self.amplitude, -1e9, 1e9)?,
            f0,
            rate: match self.sweep {
                Sweep::Linear => (f1 - f0) / d,
                Sweep::Exponential => libm::log(f1 / f0) / d,
            },
            sweep: self.sweep,
            duration_s: d,
            clock,
        })
    }
}

/// Chirp generator with an analytic phase (no accumulated frequency error).
#[derive(Debug, Clone, Copy)]
pub struct Chirp {
    amplitude: f64,
    f0: f64,
    /// Hz/s (linear) or 1/s (exponential).
    rate: f64,
    sweep: Sweep,
    duration_s: f64,
    clock: Clock,
}

impl Chirp {
    /// Instantaneous frequency in Hz at time `t_s`.
    pub fn frequency_hz(&self, t_s: f64) -> f64 {
        match self.sweep {
            Sweep::Linear => self.f0 + self.rate * t_s,
            Sweep::Exponential => self.f0 * libm::exp(self.rate * t_s),
        }
    }

    fn at(&self, t: f64) -> Setpoint {
        if t >= self.duration_s {
            return Setpoint::ZERO;
        }
        let f = self.frequency_hz(t);
        let (phi, dfdt) = match self.sweep {
            Sweep::Linear => (
                2.0 * PI * (self.f0 * t + 0.5 * self.rate * t * t),
                self.rate,
            ),
            Sweep::Exponential if self.rate == 0.0 => (2.0 * PI * self.f0 * t, 0.0),
            Sweep::Exponential => (2.0 * PI * (f - self.f0) / self.rate, self.rate * f),
        };
        Setpoint::sine(
            phi,
            2.0 * PI * f,
            2.0 * PI * dfdt,
            (self.amplitude, 0.0, 0.0),
        )
    }
}

generator_block!(Chirp, self, t => self.at(t));

/// The stepped-sine sweep of thesis §5.5.1: one segment per frequency, each with a
/// raised-cosine amplitude ramp from zero, a settling time, a measurement window of a whole
/// number of periods, and a raised-cosine ramp back to zero (so the next frequency does not
/// start on the ring an abrupt stop leaves in a lightly damped mode). Each frequency is nudged so the window
/// holds an integer number of samples as well, which puts it exactly on a DFT bin (eq 5-11).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteppedSineConfig<'a> {
    /// Requested frequencies in Hz (each below Nyquist).
    pub frequencies_hz: &'a [f64],
    /// Amplitude (unit).
    pub amplitude: f64,
    /// Periods of the amplitude ramp at the start of each segment.
    pub ramp_periods: u32,
    /// Periods to wait at full amplitude before measuring.
    pub settle_periods: u32,
    /// Periods in the measurement window (`≥ 1`).
    pub measure_periods: u32,
    /// Periods of the amplitude ramp back to zero after the window (0: an abrupt stop).
    pub ramp_down_periods: u32,
}

/// The layout of one stepped-sine segment, in samples from the start of the sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SweepSegment {
    /// The frequency actually generated, in Hz (the requested one nudged onto a DFT bin).
    pub frequency_hz: f64,
    /// First sample of the segment (ramp start).
    pub start: u64,
    /// Samples of amplitude ramp.
    pub ramp_len: u64,
    /// First sample of the measurement window.
    pub measure_start: u64,
    /// Samples in the measurement window (`measure_periods / frequency_hz` seconds exactly).
    pub measure_len: u64,
    /// Samples of the ramp back to zero after the window.
    pub ramp_down_len: u64,
}

impl SweepSegment {
    /// One past the last sample of the measurement window.
    pub fn measure_end(&self) -> u64 {
        self.measure_start + self.measure_len
    }

    /// One past the last sample of the segment (its ramp down included).
    pub fn end(&self) -> u64 {
        self.measure_end() + self.ramp_down_len
    }
}

impl<'a> SteppedSineConfig<'a> {
    /// A sweep generator ticking every `sample_period_s` s.
    pub fn try_build(&self, sample_period_s: f64) -> Result<SteppedSine<'a>, Error> {
        let clock = Clock::try_new(sample_period_s)?;
        let nyquist = 0.5 / clock.period_s;
        for &f in self.frequencies_hz {
            check_range("frequencies_hz", f, 1e-6, nyquist)?;
        }
        check_range("measure_periods", self.measure_periods as f64, 1.0, 1e9)?;
        let sweep = SteppedSine {
            config: *self,
            amplitude: check_range("amplitude", self.amplitude, -1e9, 1e9)?,
            current: None,
            index: 0,
            clock,
        };
        Ok(SteppedSine {
            current: sweep.segment_after(0, 0),
            ..sweep
        })
    }
}

/// Stepped-sine sweep generator; zero after the last segment.
///
/// ```
/// use servo_core::{Block, SteppedSineConfig};
/// let f = [100.0, 1000.0];
/// let cfg = SteppedSineConfig {
///     frequencies_hz: &f, amplitude: 1.0, ramp_periods: 2, settle_periods: 3, measure_periods: 10,
///     ramp_down_periods: 2,
/// };
/// let sweep = cfg.try_build(1.0 / 199_600.0).unwrap();
/// let seg = sweep.segment(1).unwrap();
/// // 10 periods of the nudged frequency are exactly `measure_len` samples.
/// assert!((seg.frequency_hz * seg.measure_len as f64 / 199_600.0 - 10.0).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct SteppedSine<'a> {
    config: SteppedSineConfig<'a>,
    amplitude: f64,
    current: Option<SweepSegment>,
    index: usize,
    clock: Clock,
}

impl SteppedSine<'_> {
    /// Layout of segment `i` starting at sample `start`.
    fn segment_after(&self, i: usize, start: u64) -> Option<SweepSegment> {
        let requested = *self.config.frequencies_hz.get(i)?;
        let fs = 1.0 / self.clock.period_s;
        let periods = self.config.measure_periods as f64;
        let measure_len = libm::round(periods * fs / requested).max(1.0);
        let samples_per_period = measure_len / periods;
        let ramp_len = libm::round(self.config.ramp_periods as f64 * samples_per_period) as u64;
        let settle_len = libm::round(self.config.settle_periods as f64 * samples_per_period) as u64;
        let ramp_down_len =
            libm::round(self.config.ramp_down_periods as f64 * samples_per_period) as u64;
        Some(SweepSegment {
            frequency_hz: fs / samples_per_period,
            start,
            ramp_len,
            measure_start: start + ramp_len + settle_len,
            measure_len: measure_len as u64,
            ramp_down_len,
        })
    }

    /// Layout of segment `i` (`None` past the last frequency).
    pub fn segment(&self, i: usize) -> Option<SweepSegment> {
        let mut seg = self.segment_after(0, 0)?;
        for j in 1..=i {
            seg = self.segment_after(j, seg.end())?;
        }
        Some(seg)
    }

    /// Total length of the sweep in samples.
    pub fn total_samples(&self) -> u64 {
        self.segment(self.config.frequencies_hz.len().saturating_sub(1))
            .map_or(0, |s| s.end())
    }

    fn at(&mut self, k: u64) -> Setpoint {
        let Some(mut seg) = self.current else {
            return Setpoint::ZERO;
        };
        if k >= seg.end() {
            self.index += 1;
            self.current = self.segment_after(self.index, seg.end());
            match self.current {
                Some(next) => seg = next,
                None => return Setpoint::ZERO,
            }
        }
        let t = self.clock.period_s;
        let n = (k - seg.start) as f64;
        let w = 2.0 * PI * seg.frequency_hz;
        // Raised-cosine ramps: the envelope and its slope are continuous, so a mode away from
        // the frequency is barely kicked (a linear ramp's corners kick it by ~1/(T_r·ω)).
        // Value, slope and curvature of the envelope at `u` ∈ [0, 1] of a ramp `ramp_s` long.
        let raised_cosine = |u: f64, ramp_s: f64| {
            let (s, c) = (libm::sin(PI * u), libm::cos(PI * u));
            let rate = PI / ramp_s;
            (0.5 * (1.0 - c), 0.5 * rate * s, 0.5 * rate * rate * c)
        };
        let (env, slope, curvature) = if (k - seg.start) < seg.ramp_len {
            let ramp_s = seg.ramp_len as f64 * t;
            raised_cosine(n * t / ramp_s, ramp_s)
        } else if k >= seg.measure_end() {
            let ramp_s = seg.ramp_down_len as f64 * t;
            let (env, slope, curvature) =
                raised_cosine((seg.end() - k) as f64 * t / ramp_s, ramp_s);
            (env, -slope, curvature)
        } else {
            (1.0, 0.0, 0.0)
        };
        let a = self.amplitude;
        Setpoint::sine(w * n * t, w, 0.0, (a * env, a * slope, a * curvature))
    }
}

impl Block for SteppedSine<'_> {
    type Input = ();
    type Output = Setpoint;

    #[inline]
    fn update(&mut self, _: ()) -> Setpoint {
        let k = self.clock.k;
        self.clock.tick();
        let s = self.at(k);
        self.clock.guard(s)
    }

    fn reset(&mut self) {
        self.clock.reset();
        self.index = 0;
        self.current = self.segment_after(0, 0);
    }

    fn faulted(&self) -> bool {
        self.clock.fault.is_set()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numerical derivatives of the position agree with the analytic ones (central
    /// differences, O(T²) error), relative to each derivative's peak over the record.
    fn check_derivatives(
        mut g: impl Block<Input = (), Output = Setpoint>,
        t: f64,
        n: usize,
        tol: f64,
    ) {
        let mut w = [g.update(()), g.update(()), g.update(())];
        let (mut err_v, mut err_a, mut peak_v, mut peak_a) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
        for _ in 0..n {
            let v = (w[2].position - w[0].position) / (2.0 * t);
            let a = (w[2].position - 2.0 * w[1].position + w[0].position) / (t * t);
            err_v = err_v.max((v - w[1].velocity).abs());
            err_a = err_a.max((a - w[1].acceleration).abs());
            peak_v = peak_v.max(w[1].velocity.abs());
            peak_a = peak_a.max(w[1].acceleration.abs());
            w = [w[1], w[2], g.update(())];
        }
        assert!(
            err_v < tol * peak_v,
            "velocity error {err_v} of peak {peak_v}"
        );
        assert!(
            err_a < tol * peak_a,
            "acceleration error {err_a} of peak {peak_a}"
        );
    }

    #[test]
    fn analytic_derivatives_match_finite_differences() {
        let t = 1e-6;
        let sine = SineConfig {
            amplitude: 1.0,
            frequency_hz: 200.0,
            phase_rad: 0.3,
            offset: 0.1,
        };
        check_derivatives(sine.try_build(t).unwrap(), t, 20_000, 1e-3);
        for sweep in [Sweep::Linear, Sweep::Exponential] {
            let chirp = ChirpConfig {
                amplitude: 1.0,
                f_start_hz: 10.0,
                f_end_hz: 2000.0,
                duration_s: 0.05,
                sweep,
            };
            check_derivatives(chirp.try_build(t).unwrap(), t, 40_000, 1e-3);
        }
    }

    /// §5.5.1: ramp from zero at each segment start, integer periods in the window, and the
    /// window's DFT at the segment frequency returns the full amplitude with zero leakage.
    #[test]
    fn stepped_sine_layout_and_exact_bins() {
        let fs = 199_600.0;
        let freqs = [37.0, 512.3, 4999.0];
        let cfg = SteppedSineConfig {
            frequencies_hz: &freqs,
            amplitude: 0.5,
            ramp_periods: 3,
            settle_periods: 5,
            measure_periods: 20,
            ramp_down_periods: 2,
        };
        let mut g = cfg.try_build(1.0 / fs).unwrap();
        let segs: [SweepSegment; 3] = core::array::from_fn(|i| g.segment(i).unwrap());
        assert_eq!(segs[1].start, segs[0].end());
        assert_eq!(g.total_samples(), segs[2].end());
        assert!(g.segment(3).is_none());
        let mut re = [0.0; 3];
        let mut im = [0.0; 3];
        for k in 0..g.total_samples() + 10 {
            let p = g.update(()).position;
            for (i, s) in segs.iter().enumerate() {
                if k == s.start {
                    assert_eq!(p, 0.0, "segment {i} starts from zero amplitude");
                }
                if k + 1 == s.end() {
                    let last_sample_envelope = 1.0 / s.ramp_down_len as f64;
                    assert!(
                        p.abs() <= 0.5 * last_sample_envelope,
                        "segment {i} ends near zero"
                    );
                }
                if k >= s.measure_start && k < s.measure_end() {
                    let ph = 2.0 * PI * s.frequency_hz * (k - s.measure_start) as f64 / fs;
                    re[i] += p * libm::cos(ph);
                    im[i] += p * libm::sin(ph);
                }
            }
            if k >= g.total_samples() {
                assert_eq!(p, 0.0);
            }
        }
        for (i, s) in segs.iter().enumerate() {
            assert!((s.frequency_hz / freqs[i] - 1.0).abs() < 0.01);
            let periods = s.frequency_hz * s.measure_len as f64 / fs;
            assert!((periods - 20.0).abs() < 1e-9);
            let amp = 2.0 * libm::hypot(re[i], im[i]) / s.measure_len as f64;
            assert!((amp - 0.5).abs() < 1e-9, "segment {i}: {amp}");
        }
    }

    #[test]
    fn step_and_bad_frequency() {
        let mut s = StepConfig {
            amplitude: 2.0,
            delay_s: 0.0,
        }
        .try_build(1e-3)
        .unwrap();
        assert_eq!(s.update(()).position, 2.0);
        let e = SineConfig {
            amplitude: 1.0,
            frequency_hz: 1e6,
            phase_rad: 0.0,
            offset: 0.0,
        }
        .try_build(1e-3);
        assert!(matches!(
            e,
            Err(Error::OutOfRange {
                param: "frequency_hz",
                ..
            })
        ));
    }
}
