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

/// The built-in generators: sequential, so reading `ahead` ticks early is running them early.
#[derive(Debug, Clone)]
pub(crate) enum Generator {
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
        Ok(match *spec {
            ReferenceSpec::Hold => Generator::Zero,
            ReferenceSpec::Sine {
                amplitude_m,
                frequency_hz,
            } => Generator::Sine(
                SineConfig {
                    amplitude: amplitude_m,
                    frequency_hz,
                    phase_rad: 0.0,
                    offset: 0.0,
                }
                .try_build(period_s)
                .map_err(invalid)?,
            ),
            ReferenceSpec::Step { amplitude_m, at_s } => Generator::Step(
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
            } => Generator::Chirp(
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
        })
    }

    #[inline]
    fn position(&mut self) -> f64 {
        match self {
            Generator::Zero => 0.0,
            Generator::Sine(g) => g.update(()).position,
            Generator::Step(g) => g.update(()).position,
            Generator::Chirp(g) => g.update(()).position,
        }
    }
}

impl Reference for Generator {
    fn prime(&mut self, _: &Sensor, out: &mut [f64]) {
        out.iter_mut().for_each(|v| *v = self.position());
    }

    #[inline]
    fn next(&mut self, _: &Sensor, _: usize) -> f64 {
        self.position()
    }

    fn faulted(&self) -> bool {
        match self {
            Generator::Zero => false,
            Generator::Sine(g) => g.faulted(),
            Generator::Step(g) => g.faulted(),
            Generator::Chirp(g) => g.faulted(),
        }
    }
}
