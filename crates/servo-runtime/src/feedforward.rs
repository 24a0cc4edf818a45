//! The feedforward of a loop, evaluated per tick from the previewed reference: the stage-model
//! inverse on finite differences, or a ZPETC or FIR filter whose coefficients were designed
//! offline.

use crate::fir::Fir;
use crate::preview::Window;
use servo_config::{Allowed, Invalid};
use servo_config::{FeedforwardSpec, Stage, ZPETC_SECTIONS};
use servo_core::{Block, Limits, Setpoint, Zpetc};

/// The feedforward of a loop: which law, and the FIR's storage beside it (so the law changes
/// in place and the storage is loaded in place). Fixed storage: nothing is allocated.
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct Feedforward {
    kind: Kind,
    fir: Fir,
}

/// Which feedforward law runs (a ZPETC filter's sections in place: fixed storage, nothing
/// is allocated).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
// A tag byte of its own: read and dispatched in two instructions (a tag folded into a
// variant's spare bits costs a range check and a shift at every dispatch).
#[repr(u8)]
enum Kind {
    None,
    Model(servo_core::Feedforward),
    Zpetc(Zpetc<ZPETC_SECTIONS>),
    Fir,
}

impl Feedforward {
    /// None yet: storage for [`Feedforward::rebuild`].
    pub(crate) const UNBUILT: Feedforward = Feedforward {
        kind: Kind::None,
        fir: Fir::EMPTY,
    };

    /// The feedforward of `spec` for `stage`, its output within ±`limit_v`, written in place;
    /// refused (naming the key), `self` untouched, when a filter is invalid.
    pub(crate) fn rebuild(
        &mut self,
        spec: &FeedforwardSpec,
        stage: &Stage,
        limit_v: f64,
    ) -> Result<(), Invalid> {
        self.kind = match spec {
            FeedforwardSpec::None => Kind::None,
            FeedforwardSpec::Model => Kind::Model(
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
            FeedforwardSpec::Zpetc(z) => Kind::Zpetc(z.build().map_err(|_| {
                Invalid::new(
                    "feedforward",
                    "sections",
                    f64::NAN,
                    Allowed::Text("a ZPETC filter servo-core accepts"),
                )
            })?),
            FeedforwardSpec::Fir(f) => {
                self.fir.load(f);
                Kind::Fir
            }
        };
        Ok(())
    }

    pub(crate) fn faulted(&self) -> bool {
        match &self.kind {
            Kind::None => false,
            Kind::Model(f) => f.faulted(),
            Kind::Zpetc(z) => z.faulted(),
            Kind::Fir => self.fir.faulted(),
        }
    }

    /// Back to the initial state.
    pub(crate) fn reset(&mut self) {
        match &mut self.kind {
            Kind::None => {}
            Kind::Model(f) => f.reset(),
            Kind::Zpetc(z) => z.reset(),
            Kind::Fir => self.fir.reset(),
        }
    }

    /// This tick's reference for the feedback (m) and the feedforward command (V), from the
    /// window `w` (at `period_s`, s).
    #[inline]
    pub(crate) fn evaluate(&mut self, w: &Window, period_s: f64) -> (f64, f64) {
        match &mut self.kind {
            Kind::None => (w.smooth(0), 0.0),
            Kind::Model(ff) => {
                let t = period_s;
                let (prev, now, next) = (w.smooth(-1), w.smooth(0), w.smooth(1));
                let sp = Setpoint {
                    position: now,
                    velocity: (next - prev) / (2.0 * t),
                    acceleration: (next - 2.0 * now + prev) / (t * t),
                };
                (now, ff.update(sp))
            }
            Kind::Zpetc(z) => (z.update(w.smooth(z.preview() as isize)), 0.0),
            Kind::Fir => (self.fir.evaluate(), 0.0),
        }
    }

    /// Takes this tick's window (every tick, tripped or not: a filter with a memory of the
    /// trajectory keeps it); `fresh` when the window was filled anew.
    #[inline]
    pub(crate) fn follow(&mut self, w: &Window, fresh: bool) {
        if fresh {
            self.prime(w);
        } else if let Kind::Fir = self.kind {
            self.fir.follow(w);
        }
    }

    /// Starts a filter with a memory of the trajectory from a window filled anew (the first
    /// tick, or ticks skipped): the trajectory at rest at the earliest sample the window
    /// smooths, then what it holds up to the tick before this tick's input — for the ZPETC at
    /// most `MAX_PREVIEW` section updates. Out of line: the steady tick never comes here.
    #[cold]
    #[inline(never)]
    fn prime(&mut self, w: &Window) {
        match &mut self.kind {
            Kind::Fir => self.fir.prime(w),
            Kind::Zpetc(z) => {
                z.prime(w.smooth(-1));
                for j in 0..z.preview() as isize {
                    z.update(w.smooth(j));
                }
            }
            Kind::None | Kind::Model(_) => {}
        }
    }
}
