//! # servo-core
//!
//! The `#![no_std]` blocks that run inside a fast-tool-servo tick: PID with filtered derivative
//! (thesis eq 7-8), IIR/biquad filters, discrete state-space controllers of any order (the
//! 27-state H2 controller of §6.4.1), cascade acceleration feedback (Fig 7-6), a disturbance
//! observer (Fig 7-4), model-inverse feedforward, integer and fractional delay lines, an
//! oversampling averager, setpoint generators, spindle synchronisation (encoder tracking, spiral
//! path), repetitive control on the spindle angle and freeform surfaces evaluated per tick.
//!
//! Every block follows one contract, [`Block`]: a configuration in SI units is validated once
//! by `try_build(sample_period_s)`; the tick (`update`) never allocates, never panics and
//! never validates: it clamps to limits, and a non-finite input or state zeroes the output
//! and latches a fault until [`Block::reset`].
//!
//! Arithmetic is portable by default: a build gives the same bits on every processor (and on
//! the microcontroller targets CI builds, `thumbv7em-none-eabihf`). The dense products run
//! with the widest vector instructions the machine has, chosen at run time ([`simd`]), which
//! changes their speed, not their result. Cargo feature `fma` (off by default, links `std`)
//! fuses their multiply-adds ([`ARITHMETIC`] says which a build does): other rounding,
//! recorded in the provenance of every run.
//!
//! ```
//! use servo_core::{Block, PidConfig};
//! let mut pid = PidConfig::THESIS_CH7.try_build(1.0 / 199_600.0)?;
//! let volts_to_dac = pid.update(0.01); // error in sensor volts
//! assert!(volts_to_dac > 0.0 && !pid.faulted());
//! # Ok::<(), servo_core::Error>(())
//! ```
#![no_std]

#[cfg(feature = "fma")]
extern crate std;

mod block;
mod cascade;
mod delay;
mod error;
mod feedforward;
mod iir;
mod limits;
mod math;
mod observer;
mod oversample;
mod pid;
mod repetitive;
pub mod setpoint;
pub mod simd;
mod spindle;
mod state_space;
pub mod surface;

pub use block::Block;
pub use cascade::{
    kg, AccelCascade, AccelCascadeConfig, CascadeInput, STANDARD_GRAVITY_M_S2,
    THESIS_ACCEL_SENSITIVITY_V_PER_M_S2,
};
pub use delay::{IntegerDelay, ThiranDelay, TransportDelay};
pub use error::{Error, ErrorKind};
pub use feedforward::{Feedforward, FeedforwardConfig, Zpetc, ZpetcConfig};
pub use iir::{Biquad, BiquadCascade, BiquadDesign, Iir, IirCoeffs};
pub use limits::Limits;
pub use math::{mul_add, ARITHMETIC, FUSED_ARITHMETIC};
pub use observer::{DisturbanceObserver, ObserverInput};
pub use oversample::Averager;
pub use pid::{Pid, PidCoeffs, PidConfig, PidState, Realization};
pub use repetitive::{
    Repetitive, RepetitiveConfig, RepetitiveInput, LEARNING_IDENTITY, LEARNING_TAPS, MIN_BINS,
};
pub use setpoint::{
    Chirp, ChirpConfig, Setpoint, Sine, SineConfig, Step, StepConfig, SteppedSine,
    SteppedSineConfig, Sweep, SweepSegment,
};
pub use spindle::{Encoder, SpindleTracker, SpindleTrackerConfig, Spiral};
pub use state_space::{StateSpace, StateSpaceConfig};
