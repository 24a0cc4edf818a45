//! Feedforward: the model inverse of a mass-spring-damper stage,
//! `u = (m·r̈ + c·ṙ + k·r) / gain` — the force that moves the stage along the trajectory,
//! converted to the controller's output unit (V) by the actuator gain `H_I·K_T` (N/V) — added
//! to the controller output; and the zero-phase-error tracking controller ([`Zpetc`]) that
//! reshapes the reference of the whole closed loop from a preview of the trajectory.

use crate::block::{Block, FaultLatch};
use crate::error::{check_range, Error};
use crate::iir::{BiquadCascade, IirCoeffs};
use crate::limits::Limits;
use crate::setpoint::Setpoint;

/// Plant parameters of the feedforward (SI units).
///
/// ```
/// use servo_core::{Block, FeedforwardConfig, Setpoint};
/// let mut ff = FeedforwardConfig::THESIS_HEAVY.try_build().unwrap();
/// // 1 m/s² needs 0.175 N of force, i.e. 0.175/3.6658 V at 1 A/V.
/// let u = ff.update(Setpoint { position: 0.0, velocity: 0.0, acceleration: 1.0 });
/// assert!((u - 0.175 / 3.6658).abs() < 1e-15);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FeedforwardConfig {
    /// Moving mass in kg.
    pub mass_kg: f64,
    /// Viscous damping in N·s/m.
    pub damping_n_s_per_m: f64,
    /// Suspension stiffness in N/m.
    pub stiffness_n_per_m: f64,
    /// Actuator gain in N per output unit (`H_I·K_T`, N/V).
    pub newton_per_unit: f64,
    /// Output limits.
    pub limits: Limits,
}

impl FeedforwardConfig {
    /// The heavy thesis stage (§5.7.3): 0.174 kg, flexure 21965 N/m and 2.28 N·s/m
    /// (Table 5-2), 1 A/V × 3.6658 N/A.
    pub const THESIS_HEAVY: FeedforwardConfig = FeedforwardConfig {
        mass_kg: 0.175,
        damping_n_s_per_m: 2.28,
        stiffness_n_per_m: 21965.0,
        newton_per_unit: 3.6658,
        limits: Limits::DAC_10V,
    };

    /// Validates the parameters.
    pub fn try_build(&self) -> Result<Feedforward, Error> {
        Ok(Feedforward {
            m: check_range("mass_kg", self.mass_kg, 0.0, 1e6)? / self.newton_per_unit,
            c: check_range("damping_n_s_per_m", self.damping_n_s_per_m, 0.0, 1e9)?
                / self.newton_per_unit,
            k: check_range("stiffness_n_per_m", self.stiffness_n_per_m, 0.0, 1e12)?
                / check_range("newton_per_unit", self.newton_per_unit, 1e-9, 1e9)?,
            limits: self.limits,
            fault: FaultLatch::default(),
        })
    }
}

/// Feedforward from a setpoint with analytic derivatives (see [`crate::setpoint`]).
#[derive(Debug, Clone, Copy)]
pub struct Feedforward {
    m: f64,
    c: f64,
    k: f64,
    limits: Limits,
    fault: FaultLatch,
}

impl Block for Feedforward {
    type Input = Setpoint;
    type Output = f64;

    #[inline]
    fn update(&mut self, r: Setpoint) -> f64 {
        let u = self.m * r.acceleration + self.c * r.velocity + self.k * r.position;
        if self.fault.check(u) {
            return 0.0;
        }
        self.limits.clamp(u)
    }

    fn reset(&mut self) {
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

/// A zero-phase-error tracking controller (Tomizuka 1987) as designed by
/// `design::zpetc`: `r'[k] = gain · sections(y_d[k + preview])`, so that the closed loop from
/// the modified reference `r'` to the tool follows the desired trajectory `y_d` with zero phase
/// error. Fed `preview` ticks ahead of the trajectory; padded sections are identities.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZpetcConfig<const M: usize> {
    /// Overall gain (dimensionless).
    pub gain: f64,
    /// Second-order sections with `a0 = 1`; each must be stable (the inverted zeros).
    pub sections: [IirCoeffs<2>; M],
    /// Ticks of preview the filter needs (its input leads its output by this many ticks).
    pub preview: usize,
}

impl<const M: usize> ZpetcConfig<M> {
    /// Validates the gain and that every section is finite and stable.
    pub fn try_build(&self) -> Result<Zpetc<M>, Error> {
        check_range("gain", self.gain, -1e12, 1e12)?;
        check_range("preview", self.preview as f64, 0.0, 1e6)?;
        for s in &self.sections {
            s.validate()?;
            // Schur–Cohn for 1 + a1 z⁻¹ + a2 z⁻²: |a2| < 1 and |a1| < 1 + a2.
            let [a1, a2] = s.a;
            check_range("section a2", a2, -1.0 + 1e-15, 1.0 - 1e-15)?;
            check_range("section a1", a1, -(1.0 + a2) + 1e-15, 1.0 + a2 - 1e-15)?;
        }
        Ok(Zpetc {
            gain: self.gain,
            filter: BiquadCascade::new(self.sections),
            preview: self.preview,
        })
    }
}

/// A built [`ZpetcConfig`].
#[derive(Debug, Clone, Copy)]
pub struct Zpetc<const M: usize> {
    gain: f64,
    filter: BiquadCascade<M>,
    preview: usize,
}

impl<const M: usize> Zpetc<M> {
    /// Ticks of preview: feed `y_d[k + preview]` at tick k.
    pub fn preview(&self) -> usize {
        self.preview
    }

    /// Starts from a trajectory at rest at `y` (m) forever: the filter's state as if it had
    /// been fed `y` since the beginning of time, so that a start away from zero is no step to
    /// it. The filter inverts a loop that rolls off, so its gain near Nyquist is large (10⁴ and
    /// more for a kHz loop at 200 kHz) and a step at its input would saturate the DAC.
    /// Feed it the trajectory's samples up to the preview after this (their outputs unused).
    pub fn prime(&mut self, y: f64) {
        self.filter.prime(y);
    }
}

impl<const M: usize> Block for Zpetc<M> {
    /// The desired trajectory `preview` ticks ahead (m).
    type Input = f64;
    /// The modified reference for this tick (m).
    type Output = f64;

    #[inline]
    fn update(&mut self, ahead: f64) -> f64 {
        self.gain * self.filter.update(ahead)
    }

    fn reset(&mut self) {
        self.filter.reset();
    }

    fn faulted(&self) -> bool {
        self.filter.faulted()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iir::IirCoeffs;

    /// A ZPETC inverting a slow loop: the pole factors of `T` as sections with unit DC gain
    /// and a gain of ~10⁶ each at Nyquist. Started from rest at the trajectory's value, it
    /// gives that value, where from zero the same value is a step it amplifies a billionfold.
    #[test]
    fn a_primed_filter_starts_without_a_step() {
        // (1 − p z⁻¹)² with p = 0.999, scaled to unit DC gain.
        let p = 0.999;
        let k = 1.0 / ((1.0 - p) * (1.0 - p));
        let pole_factor = IirCoeffs {
            b0: k,
            b: [-2.0 * p * k, p * p * k],
            a: [0.0, 0.0],
        };
        let config = ZpetcConfig {
            gain: 1.0,
            sections: [pole_factor, pole_factor],
            preview: 4,
        };
        let y = -9e-6;
        let mut cold = config.try_build().unwrap();
        assert!(cold.update(y).abs() > 1e3, "from zero, a step of 9 µm");
        let mut primed = config.try_build().unwrap();
        primed.prime(y);
        // To the sections' own rounding: each multiplies ε by its ~4·10⁶ coefficients.
        for _ in 0..5 {
            let out = primed.update(y);
            assert!((out - y).abs() < 1e-3 * y.abs(), "{out}");
        }
    }
}
