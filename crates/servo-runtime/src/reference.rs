//! Where the desired trajectory comes from: the deployment's built-in generator, or a host's
//! own trajectory (a machine's tool path, a spindle-synchronised surface) through the
//! [`Reference`] trait.

use daq_io::Sensor;
use servo_config::ReferenceSpec;
use servo_config::{Allowed, Invalid};
use servo_core::{Block, Chirp, ChirpConfig, Sine, SineConfig, Step, StepConfig, Sweep};

/// A desired trajectory (m, positive away from the workpiece), read ahead by the loop's
/// preview: what a host passes to [`crate::Servo::tick_with`]. Called on the ticking thread:
/// no allocation, no lock, no panic.
pub trait Reference {
    /// At the first tick, and at the first tick after samples were skipped (a loop that fell
    /// behind takes the newest sample: its `seq` jumps): `out[j]` = the desired position `j`
    /// ticks after the tick of `sample`, for every `j < out.len()` (the preview plus one). It
    /// may be asked again for ticks it already gave.
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]);
    /// At each later tick: the desired position `ahead` ticks after the tick of `sample`
    /// (`ahead` is the preview, the same every tick).
    fn next(&mut self, sample: &Sensor, ahead: usize) -> f64;
    /// The trajectory lost its source (a spindle's lock): the loop trips to its safe state.
    fn faulted(&self) -> bool {
        false
    }
}

/// A built-in generator on the samples' ticks: its value is a closed form of the tick's time
/// (`seq · period`), primed at a sample's tick and then read in sequence `ahead` ticks early.
/// The loop primes it again after skipped ticks (a loop that fell behind takes the newest
/// sample), which moves it to that sample's tick, so the trajectory stays on the plant's time.
/// A run whose first sample is not tick 0 starts the trajectory at that tick's time.
#[derive(Debug, Clone)]
pub(crate) struct Generator {
    kind: Kind,
}

/// The generator's kind.
#[derive(Debug, Clone)]
// A tag byte of its own: read and dispatched in two instructions (a tag folded into a
// variant's spare bits costs a range check and a shift at every dispatch).
#[repr(u8)]
enum Kind {
    Zero,
    Sine(Sine),
    Step(Step),
    Chirp(Chirp),
}

impl Generator {
    /// Holds position 0.
    pub(crate) const HOLD: Generator = Generator { kind: Kind::Zero };

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
        Ok(Generator { kind })
    }

    /// Makes the next evaluation give tick `tick` (constant time).
    fn seek(&mut self, tick: u64) {
        match &mut self.kind {
            Kind::Zero => {}
            Kind::Sine(g) => g.seek(tick),
            Kind::Step(g) => g.seek(tick),
            Kind::Chirp(g) => g.seek(tick),
        }
    }

    /// The position of the next tick in sequence.
    #[inline]
    fn position(&mut self) -> f64 {
        match &mut self.kind {
            Kind::Zero => 0.0,
            Kind::Sine(g) => g.update(()).position,
            Kind::Step(g) => g.update(()).position,
            Kind::Chirp(g) => g.update(()).position,
        }
    }
}

impl Reference for Generator {
    fn prime(&mut self, sample: &Sensor, out: &mut [f64]) {
        self.seek(sample.seq);
        out.iter_mut().for_each(|v| *v = self.position());
    }

    /// The next tick in sequence: `ahead` after the sample's while no tick is skipped (the
    /// loop primes the generator again when one is).
    #[inline]
    fn next(&mut self, _: &Sensor, _: usize) -> f64 {
        self.position()
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
