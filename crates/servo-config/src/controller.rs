//! The feedback controller of a loop, built from its [`ControllerSpec`]: PID, the acceleration
//! cascade, or a state-space controller of any order up to [`MAX_SS_ORDER`] held in fixed
//! storage (servo-core's `StateSpace` for the largest order, loaded in place with the file's;
//! the tick runs the const-generic product of that order, and nothing is allocated).

use crate::check::{Allowed, Invalid};
use crate::deployment::{ControllerKind, ControllerSpec, SsMatrices, Stage, MAX_SS_ORDER};
use servo_core::{
    kg, AccelCascade, AccelCascadeConfig, BiquadDesign, Block, CascadeInput, Iir, IirCoeffs,
    Limits, Pid, PidConfig, StateSpace,
};

/// A single-input single-output state-space controller of order 1 to [`MAX_SS_ORDER`], in
/// storage for the largest: loaded in place (a microcontroller builds its loop where it runs),
/// ticked by the const-generic product of its order.
#[derive(Debug, Clone)]
#[repr(C)]
struct AnyStateSpace {
    /// The order loaded (0: none; the output is then 0).
    order: usize,
    ss: StateSpace<MAX_SS_ORDER, 1, 1>,
}

impl AnyStateSpace {
    /// Nothing loaded.
    const EMPTY: Self = AnyStateSpace {
        order: 0,
        ss: StateSpace::EMPTY,
    };

    /// Loads `m` in place (the storage untouched when refused).
    fn load(
        &mut self,
        m: &SsMatrices,
        period_s: f64,
        limits: Limits,
    ) -> Result<(), servo_core::Error> {
        self.ss
            .load(m.order(), |i, j| m.entry(i, j), limits, period_s)?;
        self.order = m.order();
        Ok(())
    }

    fn faulted(&self) -> bool {
        self.ss.faulted()
    }

    fn reset(&mut self) {
        self.ss.reset()
    }
}

/// [`AnyStateSpace::update`] for the orders `1..=MAX_SS_ORDER` (the list build.rs writes).
macro_rules! state_space_orders {
    ($($n:literal),+ $(,)?) => {
        impl AnyStateSpace {
            // Out of line: the storage's own address is the base of every matrix load (one
            // instruction each on a Cortex-M7) instead of the loop's, tens of KiB away.
            #[inline(never)]
            fn update(&mut self, e: f64) -> f64 {
                match self.order {
                    $($n => self.ss.update_order::<$n>([e])[0],)+
                    _ => 0.0,
                }
            }
        }
    };
}

// Orders 1..=MAX_SS_ORDER (the build's cap, `FTS_SERVO_MAX_SS_ORDER`; build.rs).
include!(concat!(env!("OUT_DIR"), "/orders.rs"));

/// Which law a controller runs (a state space's storage is beside it, not in it: the variant
/// changes in place, the storage is loaded in place).
#[derive(Debug, Clone)]
// A tag byte of its own: read and dispatched in two instructions (a tag folded into a
// variant's spare bits costs a range check and a shift at every dispatch).
#[repr(u8)]
enum Kind {
    Ss,
    Pid(Pid),
    Accel(AccelCascade<Iir<2>>),
}

/// The feedback law of a loop alone, in its running state: position error and accelerometer
/// reading in V → command in V (what `servo_runtime::Servo` runs inside its tick, for a host that
/// closes a loop of its own — a frequency-response measurement with an injection added to the
/// command). Plain data: moving it copies it, dropping it frees nothing.
///
/// ```
/// use servo_config::{Controller, Deployment};
/// let d = Deployment::thesis_prototype();
/// let mut c = Controller::build(&d.controller, &d.stage, d.period_s())?;
/// let u = c.update(1e-3, 0.0); // 1 mV of position error in sensor volts
/// assert!(u > 1.65e-3 && !c.faulted());
/// # Ok::<(), servo_config::Invalid>(())
/// ```
#[derive(Debug, Clone)]
#[repr(C)] // the law first, a state space's storage last (see `servo_runtime::Servo`)
pub struct Controller {
    kind: Kind,
    /// A state-space law's storage (loaded when `kind` is `Ss`).
    ss: AnyStateSpace,
    /// Output limit in V.
    limit_v: f64,
}

/// The acceleration shaping filter Ha of `c` (None: no filter): a first-order low pass or a
/// Butterworth at `accel_filter_hz`, by `accel_filter_order`.
pub fn accel_shaping(c: &ControllerSpec) -> Option<BiquadDesign> {
    let f0_hz = c.accel_filter_hz;
    (f0_hz > 0.0).then_some(match c.accel_filter_order {
        1 => BiquadDesign::FirstOrderLowPass { f0_hz },
        _ => BiquadDesign::LowPass {
            f0_hz,
            q: core::f64::consts::FRAC_1_SQRT_2,
        },
    })
}

/// The position PID `c` runs, after Kg scaling (§7.4.1) for an `accel` controller with
/// `kg_scaling` on `stage`.
pub fn position_pid(c: &ControllerSpec, stage: &Stage) -> Result<PidConfig, Invalid> {
    let limits = Limits::try_new(-c.limit_v, c.limit_v).map_err(|_| {
        Invalid::new(
            "controller",
            "limit_v",
            c.limit_v,
            Allowed::Text("(0, 10] V (the DAC range)"),
        )
    })?;
    let pid = PidConfig {
        kp: c.pid.kp,
        ki: c.pid.ki,
        kd: c.pid.kd,
        tf_s: c.pid.tf_s,
        limits,
    };
    Ok(if c.kind == ControllerKind::Accel && c.kg_scaling {
        pid.with_gain_scale(1.0 / kg_of(c, stage))
    } else {
        pid
    })
}

/// Kg of §7.4.1 for the acceleration gain of `c` on `stage` (dimensionless).
pub fn kg_of(c: &ControllerSpec, stage: &Stage) -> f64 {
    kg(
        stage.suspended_mass_kg,
        c.ka,
        stage.accel_sensitivity_v_per_m_s2,
        stage.current_gain_a_per_v,
        stage.kt_n_per_a,
    )
}

/// A law's command `u`, or NaN when the law has latched a fault.
#[inline(always)]
fn nan_if_faulted(u: f64, faulted: bool) -> f64 {
    if faulted {
        f64::NAN
    } else {
        u
    }
}

/// A servo-core build error as the key of `[controller]` it came from.
fn block_error(e: servo_core::Error, key: &'static str) -> Invalid {
    match e {
        servo_core::Error::OutOfRange {
            param,
            value,
            min,
            max,
        } => Invalid::new(
            "controller",
            pid_key(param).unwrap_or(key),
            value,
            Allowed::between(min, max, ""),
        ),
        servo_core::Error::NotFinite { param } => Invalid::new(
            "controller",
            pid_key(param).unwrap_or(key),
            f64::NAN,
            Allowed::Text("a finite number"),
        ),
        _ => Invalid::new("controller", key, f64::NAN, Allowed::Text("a valid value")),
    }
}

/// `pid.kp` … for a PID parameter's name.
fn pid_key(param: &str) -> Option<&'static str> {
    Some(match param {
        "kp" => "pid.kp",
        "ki" => "pid.ki",
        "kd" => "pid.kd",
        "tf_s" => "pid.tf_s",
        _ => return None,
    })
}

impl Controller {
    /// No law yet: its output is 0 V. Storage for [`Controller::rebuild`] (a
    /// microcontroller's static loop).
    pub const UNBUILT: Controller = Controller {
        kind: Kind::Ss,
        ss: AnyStateSpace::EMPTY,
        limit_v: 0.0,
    };

    /// The controller of `c` on `stage` at `period_s` (s), in its initial state.
    pub fn build(c: &ControllerSpec, stage: &Stage, period_s: f64) -> Result<Self, Invalid> {
        let mut built = Controller::UNBUILT;
        built.rebuild(c, stage, period_s)?;
        Ok(built)
    }

    /// [`Controller::build`] in place: the controller of `c` on `stage` at `period_s` (s), in
    /// its initial state, written where `self` lies (no copy of a state space's storage on
    /// the stack). Refused, `self` untouched, as `build` refuses.
    pub fn rebuild(
        &mut self,
        c: &ControllerSpec,
        stage: &Stage,
        period_s: f64,
    ) -> Result<(), Invalid> {
        let pid_cfg = position_pid(c, stage)?;
        let limits = pid_cfg.limits;
        self.kind = match c.kind {
            ControllerKind::Pid => Kind::Pid(
                pid_cfg
                    .try_build(period_s)
                    .map_err(|e| block_error(e, "pid"))?,
            ),
            ControllerKind::Accel => {
                let ha = match accel_shaping(c) {
                    Some(d) => d
                        .try_coeffs(period_s)
                        .map_err(|e| block_error(e, "accel_filter_hz"))?,
                    None => IirCoeffs::<2>::IDENTITY,
                };
                pid_cfg
                    .try_build(period_s)
                    .map_err(|e| block_error(e, "pid"))?;
                Kind::Accel(
                    AccelCascadeConfig {
                        pid: pid_cfg,
                        ka: c.ka,
                        limits,
                    }
                    .try_build(period_s, Iir::new(ha))
                    .map_err(|e| block_error(e, "ka"))?,
                )
            }
            ControllerKind::Ss => {
                let m = c.ss.as_ref().ok_or(Invalid::new(
                    "controller",
                    "ss",
                    f64::NAN,
                    Allowed::Text("the matrices of a state-space controller for kind = \"ss\""),
                ))?;
                self.ss
                    .load(m, period_s, limits)
                    .map_err(|e| block_error(e, "ss.a"))?;
                Kind::Ss
            }
        };
        self.limit_v = c.limit_v;
        Ok(())
    }

    /// The output limit in V (the command is clipped to ±this).
    pub fn limit_v(&self) -> f64 {
        self.limit_v
    }

    /// The controller latched a fault (a non-finite input or state): its output is 0 V until
    /// it is rebuilt.
    pub fn faulted(&self) -> bool {
        match &self.kind {
            Kind::Pid(p) => p.faulted(),
            Kind::Accel(a) => a.faulted(),
            Kind::Ss => self.ss.faulted(),
        }
    }

    /// Back to the initial state (zero states, fault cleared).
    pub fn reset(&mut self) {
        match &mut self.kind {
            Kind::Pid(p) => p.reset(),
            Kind::Accel(a) => a.reset(),
            Kind::Ss => self.ss.reset(),
        }
    }

    /// One tick: position error and accelerometer reading in V → command in V; NaN once the
    /// controller has latched a fault ([`Controller::faulted`]), so that a caller's check of
    /// its command for NaN also catches the latch (the block alone gives 0 V).
    #[inline]
    pub fn update(&mut self, error_v: f64, accel_v: f64) -> f64 {
        match &mut self.kind {
            Kind::Pid(p) => nan_if_faulted(p.update(error_v), p.faulted()),
            Kind::Accel(a) => {
                let input = CascadeInput {
                    error: error_v,
                    accel: accel_v,
                };
                nan_if_faulted(a.update(input), a.faulted())
            }
            Kind::Ss => {
                let u = self.ss.update(error_v);
                nan_if_faulted(u, self.ss.faulted())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ControllerKind, Deployment, SsMatrices};

    /// Each law latches a non-finite input and then reads NaN (whatever its input) until
    /// reset: what the runtime's one NaN check on its command relies on.
    #[test]
    fn a_latched_fault_reads_as_nan_until_reset() {
        let d = Deployment::thesis_prototype();
        // x' = 0.5 x + e, u = x + 2 e: a stable first-order law.
        let ss = SsMatrices::from_fn(1, |i, j| [[0.5, 1.0], [1.0, 2.0]][i][j]).unwrap();
        for kind in [
            ControllerKind::Pid,
            ControllerKind::Accel,
            ControllerKind::Ss,
        ] {
            let mut spec = d.controller.clone();
            (spec.kind, spec.ss) = (kind, Some(ss.clone()));
            let mut c = Controller::build(&spec, &d.stage, d.period_s()).unwrap();
            assert!(c.update(1e-3, 0.0).is_finite(), "{kind:?}");
            assert!(c.update(f64::NAN, 0.0).is_nan(), "{kind:?}");
            assert!(c.faulted(), "{kind:?}");
            assert!(c.update(1e-3, 0.0).is_nan(), "{kind:?}: the latch holds");
            c.reset();
            let u = c.update(1e-3, 0.0);
            assert!(u.is_finite() && u != 0.0 && !c.faulted(), "{kind:?}");
        }
    }
}
