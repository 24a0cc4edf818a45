//! Cascade acceleration feedback, thesis Fig 7-3 and 7-6:
//! `u = PID(r − y) − Ha(Ka · a_meas)`, and the global PID gain factor `Kg` of §7.4.1.

use crate::block::{Block, FaultLatch};
use crate::error::{check_range, Error};
use crate::limits::Limits;
use crate::pid::{Pid, PidConfig};

/// Standard gravity in m/s², to convert accelerometer sensitivities given per g.
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// Thesis accelerometer sensitivity (Table 7-2, 1000 mV/g) in V/(m/s²).
pub const THESIS_ACCEL_SENSITIVITY_V_PER_M_S2: f64 = 1.0 / STANDARD_GRAVITY_M_S2;

/// The thesis's global gain factor `Kg = M / (M + Ka·S_acc·H_I·K_T)` (§7.4.1, ideal sensors).
///
/// Acceleration feedback adds `Ka·S_acc·H_I·K_T` kg to the moving mass (Table 7-1); multiplying
/// the closed loop's numerator and denominator by `Kg` keeps reference tracking unchanged, which
/// amounts to dividing the PID gains by `Kg` (see [`PidConfig::with_gain_scale`]).
///
/// * `mass_kg` — moving mass M in kg;
/// * `ka` — acceleration gain (V/V on accelerometer volts);
/// * `accel_v_per_m_s2` — accelerometer sensitivity S_acc in V/(m/s²);
/// * `current_a_per_v` — current-loop DC gain H_I in A/V;
/// * `kt_n_per_a` — motor force constant K_T in N/A.
///
/// ```
/// use servo_core::{kg, THESIS_ACCEL_SENSITIVITY_V_PER_M_S2 as S};
/// // 0.174 kg stage, Ka = 1, 1 A/V, K_T = 3.6658 N/A: the added mass is 0.374 kg.
/// let k = kg(0.175, 1.0, S, 1.0, 3.6658);
/// assert!((k - 0.175 / (0.175 + 3.6658 * S)).abs() < 1e-15);
/// ```
pub fn kg(
    mass_kg: f64,
    ka: f64,
    accel_v_per_m_s2: f64,
    current_a_per_v: f64,
    kt_n_per_a: f64,
) -> f64 {
    mass_kg / (mass_kg + ka * accel_v_per_m_s2 * current_a_per_v * kt_n_per_a)
}

impl PidConfig {
    /// The same PID with `kp`, `ki` and `kd` multiplied by `factor` (`1/Kg` for §7.4.1).
    pub fn with_gain_scale(self, factor: f64) -> PidConfig {
        PidConfig {
            kp: self.kp * factor,
            ki: self.ki * factor,
            kd: self.kd * factor,
            ..self
        }
    }
}

/// One tick's measurements for the cascade loop.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CascadeInput {
    /// Position error `r − y` (sensor unit, V in the thesis).
    pub error: f64,
    /// Measured acceleration (accelerometer unit, V in the thesis).
    pub accel: f64,
}

/// Settings of the cascade loop: position PID, acceleration gain and total output limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelCascadeConfig {
    /// Position-loop PID (its own limits bound the PID term).
    pub pid: PidConfig,
    /// Acceleration feedback gain Ka (output unit per accelerometer unit), `≥ 0`.
    pub ka: f64,
    /// Limits on the total output.
    pub limits: Limits,
}

impl AccelCascadeConfig {
    /// Builds the loop at `sample_period_s` (s) with the acceleration shaping filter `ha`
    /// (DC gain 1 by convention; [`crate::Iir::new`] with [`crate::IirCoeffs::IDENTITY`] for none).
    pub fn try_build<H>(&self, sample_period_s: f64, ha: H) -> Result<AccelCascade<H>, Error>
    where
        H: Block<Input = f64, Output = f64>,
    {
        Ok(AccelCascade {
            pid: self.pid.try_build(sample_period_s)?,
            ka: check_range("ka", self.ka, 0.0, 1e6)?,
            ha,
            limits: self.limits,
            fault: FaultLatch::default(),
        })
    }
}

/// Cascade acceleration feedback controller (Fig 7-6).
#[derive(Debug, Clone)]
pub struct AccelCascade<H> {
    pid: Pid,
    ka: f64,
    ha: H,
    limits: Limits,
    fault: FaultLatch,
}

impl<H> AccelCascade<H> {
    /// The position PID, e.g. to change its gains bumplessly at run time.
    pub fn pid_mut(&mut self) -> &mut Pid {
        &mut self.pid
    }

    /// Changes Ka at run time (values below 0 or non-finite are ignored; returns whether set).
    pub fn set_ka(&mut self, ka: f64) -> bool {
        let ok = ka.is_finite() && ka >= 0.0;
        if ok {
            self.ka = ka;
        }
        ok
    }
}

impl<H: Block<Input = f64, Output = f64>> Block for AccelCascade<H> {
    type Input = CascadeInput;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: CascadeInput) -> f64 {
        let position = self.pid.update(x.error);
        let accel = self.ha.update(self.ka * x.accel);
        let faulted = self.fault.check(x.error + x.accel) | self.pid.faulted() | self.ha.faulted();
        if faulted {
            return 0.0;
        }
        self.limits.clamp(position - accel)
    }

    fn reset(&mut self) {
        self.pid.reset();
        self.ha.reset();
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set() || self.pid.faulted() || self.ha.faulted()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iir::{Iir, IirCoeffs};

    #[test]
    fn output_is_pid_minus_scaled_acceleration() {
        let cfg = AccelCascadeConfig {
            pid: PidConfig::THESIS_CH7,
            ka: 4.0,
            limits: Limits::DAC_10V,
        };
        let mut c = cfg
            .try_build(5e-6, Iir::new(IirCoeffs::<1>::IDENTITY))
            .unwrap();
        let mut pid = PidConfig::THESIS_CH7.try_build(5e-6).unwrap();
        for k in 0..100 {
            let e = 1e-3 * libm::sin(k as f64 * 0.1);
            let a = 0.02 * libm::cos(k as f64 * 0.3);
            let u = c.update(CascadeInput { error: e, accel: a });
            assert!((u - (pid.update(e) - 4.0 * a)).abs() < 1e-15);
        }
    }

    /// §7.4.1, eq 7-10 with ideal sensors (H_I = H_a = 1) on a pure mass (C = K = 0): with the
    /// PID gains divided by Kg, X/r with acceleration feedback equals X/r without it.
    #[test]
    fn kg_scaled_pid_keeps_reference_tracking() {
        let (m, ka, kt) = (0.175, 4.0, 3.6658);
        let s_acc = THESIS_ACCEL_SENSITIVITY_V_PER_M_S2;
        let s_capa = 0.16e6; // V/m
        let base = PidConfig::THESIS_CH7;
        let scaled = base.with_gain_scale(1.0 / kg(m, ka, s_acc, 1.0, kt));
        // X/r(jω) = H·K_T / ((M + Ka·S_acc·K_T)(jω)² + H·S_capa·K_T), complex as (re, im).
        let tracking = |pid: &PidConfig, ka: f64, w: f64| {
            let (tf_re, tf_im) = (1.0, pid.tf_s * w);
            let d_mag2 = tf_re * tf_re + tf_im * tf_im;
            // Kd·jω/(1 + jωTf) = Kd·jω·(1 − jωTf)/|1 + jωTf|²
            let h = (
                pid.kp + pid.kd * w * w * pid.tf_s / d_mag2,
                -pid.ki / w + pid.kd * w / d_mag2,
            );
            let num = (h.0 * kt, h.1 * kt);
            let den = (
                -(m + ka * s_acc * kt) * w * w + h.0 * s_capa * kt,
                h.1 * s_capa * kt,
            );
            let d2 = den.0 * den.0 + den.1 * den.1;
            (
                (num.0 * den.0 + num.1 * den.1) / d2,
                (num.1 * den.0 - num.0 * den.1) / d2,
            )
        };
        for w in [10.0, 1e3, 3e3, 1e4, 1e5] {
            let (a, b) = (tracking(&base, 0.0, w), tracking(&scaled, ka, w));
            assert!(
                (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12,
                "ω={w}"
            );
            // And without the scaling the tracking does change (the test can fail).
            let c = tracking(&base, ka, w);
            let rel = libm::hypot(a.0 - c.0, a.1 - c.1) / libm::hypot(a.0, a.1);
            assert!(rel > 1e-3 || w < 100.0, "ω={w}: {rel}");
        }
    }
}
