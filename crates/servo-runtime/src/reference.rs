//! Where the desired trajectory comes from: the deployment's built-in generator, or a host's
//! own trajectory (a machine's tool path, a spindle-synchronised surface) through the
//! [`Reference`] trait.

use crate::check::{Allowed, Invalid};
use crate::deployment::ReferenceSpec;
use daq_io::Sensor;
use servo_core::{Block, Chirp, ChirpConfig, Sine, SineConfig, Step, StepConfig, Sweep};

/// A desired trajectory (m, positive away from the workpiece), read ahead by the loop's
/// preview: what a host passes to [`crate::Servo::tick_with`]. Called on the ticking thread:
/// no allocation, no lock, no panic.
pub trait Reference {
    /// At the first tick: `out[j]` = the desired position `j` ticks after the tick of
    /// `sample`, for every `j < out.len()` (the preview plus one).
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]);
    /// At each later tick: the desired position `ahead` ticks after the tick of `sample`
    /// (`ahead` is the preview, the same every tick).
    fn next(&mut self, sample: &Sensor, ahead: usize) -> f64;
    /// The trajectory lost its source (a spindle's lock): the loop trips to its safe state.
    fn faulted(&self) -> bool {
        false
    }
}

/// A built-in generator on the samples' ticks: it is sequential (reading `ahead` ticks early is
/// running it early), and a sample that skips ticks (a loop that fell behind takes the newest)
/// moves it on by as many, so the trajectory stays on the plant's time.
#[derive(Debug, Clone)]
pub(crate) struct Generator {
    kind: Kind,
    /// The tick whose position the next evaluation gives.
    next_tick: u64,
}

/// The generator's kind.
#[derive(Debug, Clone)]
enum Kind {
    Zero,
    Sine(Sine),
    Step(Step),
    Chirp(Chirp),
}

impl Generator {
    /// The generator of `spec` at `period_s` (s).
    pub(crate) fn build(spec: &ReferenceSpec, period_s: f64) -> Result<Self, Invalid> {
        let invalid = |e: servo_core::Error| match e {
            servo_core::Error::OutOfRange {
                param,
                value,
                min,
                max,
            } => Invalid::new("reference", param, value, Allowed::between(min, max, "")),
            _ => Invalid::new(
                "reference",
                "kind",
                f64::NAN,
                Allowed::Text("finite values"),
            ),
        };
        let kind = match *spec {
            ReferenceSpec::Hold => Kind::Zero,
            ReferenceSpec::Sine {
                amplitude_m,
                frequency_hz,
            } => Kind::Sine(
                SineConfig {
                    amplitude: amplitude_m,
                    frequency_hz,
                    phase_rad: 0.0,
                    offset: 0.0,
                }
                .try_build(period_s)
                .map_err(invalid)?,
            ),
            ReferenceSpec::Step { amplitude_m, at_s } => Kind::Step(
                StepConfig {
                    amplitude: amplitude_m,
                    delay_s: at_s,
                }
                .try_build(period_s)
                .map_err(invalid)?,
            ),
            ReferenceSpec::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
                duration_s,
            } => Kind::Chirp(
                ChirpConfig {
                    amplitude: amplitude_m,
                    f_start_hz,
                    f_end_hz,
                    duration_s,
                    sweep: Sweep::Exponential,
                }
                .try_build(period_s)
                .map_err(invalid)?,
            ),
        };
        Ok(Generator { kind, next_tick: 0 })
    }

    /// The position at tick `tick`: the generator moved on to it when it is ahead (constant
    /// time), the next one in sequence otherwise (a host whose ticks do not advance `seq`).
    #[inline]
    fn position_at(&mut self, tick: u64) -> f64 {
        let skipped = tick.saturating_sub(self.next_tick);
        self.next_tick = self.next_tick.max(tick).saturating_add(1);
        match &mut self.kind {
            Kind::Zero => 0.0,
            Kind::Sine(g) => {
                g.skip(skipped);
                g.update(()).position
            }
            Kind::Step(g) => {
                g.skip(skipped);
                g.update(()).position
            }
            Kind::Chirp(g) => {
                g.skip(skipped);
                g.update(()).position
            }
        }
    }
}

impl Reference for Generator {
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]) {
        for (j, v) in out.iter_mut().enumerate() {
            *v = self.position_at(sample.seq.saturating_add(j as u64));
        }
    }

    #[inline]
    fn next(&mut self, sample: &Sensor, ahead: usize) -> f64 {
        self.position_at(sample.seq.saturating_add(ahead as u64))
    }

    fn faulted(&self) -> bool {
        match &self.kind {
            Kind::Zero => false,
            Kind::Sine(g) => g.faulted(),
            Kind::Step(g) => g.faulted(),
            Kind::Chirp(g) => g.faulted(),
        }
    }
}
