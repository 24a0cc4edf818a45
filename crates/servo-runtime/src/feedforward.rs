//! The feedforward of a loop, evaluated per tick from the previewed reference: the stage-model
//! inverse on finite differences, or a ZPETC or FIR filter whose coefficients were designed
//! offline.

use crate::fir::Fir;
use crate::preview::Window;
use servo_config::{Allowed, Invalid};
use servo_config::{FeedforwardSpec, Stage, ZPETC_SECTIONS};
use servo_core::{Block, Limits, Setpoint, Zpetc};

/// A feedforward ready to run.
// Fixed storage: nothing is allocated.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub(crate) enum Feedforward {
    /// Feedback only.
    None,
    /// Stage-model inverse on finite differences of the window (V).
    Model(servo_core::Feedforward),
    /// Reshaped reference (m).
    Zpetc(Zpetc<ZPETC_SECTIONS>),
    /// Reshaped reference (m) by fixed taps over the trajectory's past.
    Fir(Fir),
}

impl Feedforward {
    /// The feedforward of `spec` on `stage`, clamped to ±`limit_v`.
    pub(crate) fn build(
        spec: &FeedforwardSpec,
        stage: &Stage,
        limit_v: f64,
    ) -> Result<Self, Invalid> {
        Ok(match spec {
            FeedforwardSpec::None => Feedforward::None,
            FeedforwardSpec::Model => Feedforward::Model(
                servo_core::FeedforwardConfig {
                    mass_kg: stage.suspended_mass_kg,
                    damping_n_s_per_m: stage.damping_n_s_per_m,
                    stiffness_n_per_m: stage.stiffness_n_per_m,
                    newton_per_unit: stage.current_gain_a_per_v * stage.kt_n_per_a,
                    limits: Limits::try_new(-limit_v, limit_v).map_err(|_| {
                        Invalid::new("controller", "limit_v", limit_v, Allowed::Text("(0, 10] V"))
                    })?,
                }
                .try_build()
                .map_err(|_| {
                    Invalid::new(
                        "stage",
                        "suspended_mass_kg",
                        stage.suspended_mass_kg,
                        Allowed::Text("a valid stage for feedforward"),
                    )
                })?,
            ),
            FeedforwardSpec::Zpetc(z) => Feedforward::Zpetc(z.build().map_err(|_| {
                Invalid::new(
                    "feedforward",
                    "sections",
                    f64::NAN,
                    Allowed::Text("a ZPETC filter servo-core accepts"),
                )
            })?),
            FeedforwardSpec::Fir(f) => Feedforward::Fir(Fir::new(f)),
        })
    }

    /// A block latched a fault.
    pub(crate) fn faulted(&self) -> bool {
        match self {
            Feedforward::None => false,
            Feedforward::Model(f) => f.faulted(),
            Feedforward::Zpetc(z) => z.faulted(),
            Feedforward::Fir(f) => f.faulted(),
        }
    }

    /// Back to the initial state.
    pub(crate) fn reset(&mut self) {
        match self {
            Feedforward::None => {}
            Feedforward::Model(f) => f.reset(),
            Feedforward::Zpetc(z) => z.reset(),
            Feedforward::Fir(f) => f.reset(),
        }
    }

    /// This tick's reference for the feedback (m) and the feedforward command (V), from the
    /// window `w` (at `period_s`, s).
    #[inline]
    pub(crate) fn evaluate(&mut self, w: &Window, period_s: f64) -> (f64, f64) {
        match self {
            Feedforward::None => (w.smooth(0), 0.0),
            Feedforward::Model(ff) => {
                let t = period_s;
                let (prev, now, next) = (w.smooth(-1), w.smooth(0), w.smooth(1));
                let sp = Setpoint {
                    position: now,
                    velocity: (next - prev) / (2.0 * t),
                    acceleration: (next - 2.0 * now + prev) / (t * t),
                };
                (now, ff.update(sp))
            }
            Feedforward::Zpetc(z) => (z.update(w.smooth(z.preview() as isize)), 0.0),
            Feedforward::Fir(f) => (f.evaluate(), 0.0),
        }
    }

    /// Takes this tick's window (every tick, tripped or not: a filter with a memory of the
    /// trajectory keeps it); `fresh` when the window was filled anew.
    #[inline]
    pub(crate) fn follow(&mut self, w: &Window, fresh: bool) {
        if fresh {
            self.prime(w);
        } else if let Feedforward::Fir(f) = self {
            f.follow(w);
        }
    }

    /// Starts a filter with a memory of the trajectory from a window filled anew (the first
    /// tick, or ticks skipped): the trajectory at rest at the earliest sample the window
    /// smooths, then what it holds up to the tick before this tick's input — for the ZPETC at
    /// most `MAX_PREVIEW` section updates. Out of line: the steady tick never comes here.
    #[cold]
    #[inline(never)]
    fn prime(&mut self, w: &Window) {
        match self {
            Feedforward::Fir(f) => f.prime(w),
            Feedforward::Zpetc(z) => {
                z.prime(w.smooth(-1));
                for j in 0..z.preview() as isize {
                    z.update(w.smooth(j));
                }
            }
            Feedforward::None | Feedforward::Model(_) => {}
        }
    }
}
