//! PID with first-order filtered derivative, thesis eq 7-8: `Kp + Ki/s + Kd·s/(Tf·s + 1)`.
//!
//! Discretisation: Tustin (bilinear, `s = (2/T)(1 − z⁻¹)/(1 + z⁻¹)`, no pre-warp) for both the
//! integral and the filtered derivative, so the integral of a ramp is exact (trapezoidal rule) and
//! the derivative filter pole sits at `(2Tf − T)/(2Tf + T)`:
//!
//! ```text
//! i[k]  = i[k−1] + Ki·T/2·(e[k] + e[k−1])                      (skipped while winding up)
//! df[k] = ((2Tf − T)·df[k−1] + 2·(e[k] − e[k−1])) / (2Tf + T)   (filtered de/dt)
//! u[k]  = clamp(Kp·e[k] + i[k] + Kd·df[k])
//! ```
//!
//! Anti-windup is conditional integration ("clamping"): while the unclamped output is beyond a
//! limit and the error would drive it further, the integrator holds. Gain changes at run time are
//! bumpless: the integrator absorbs the step the new proportional and derivative gains would
//! cause, so the output is continuous.

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};
use crate::limits::Limits;
use crate::math::flush;

/// PID settings in physical units. The error and output units are the caller's (the thesis
/// works in volts of sensor signal in, volts to the current amplifier out: V/V gains).
///
/// ```
/// use servo_core::{Block, PidConfig};
/// // Thesis §7.5.3 gains at the 199.6 kHz servo rate.
/// let mut pid = PidConfig::THESIS_CH7.try_build(1.0 / 199_600.0).unwrap();
/// let u = pid.update(1e-3);
/// assert!(u > 1.65e-3);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidConfig {
    /// Proportional gain (output unit per error unit).
    pub kp: f64,
    /// Integral gain (output unit per error unit per second), `≥ 0`.
    pub ki: f64,
    /// Derivative gain (output unit · s per error unit), `≥ 0`.
    pub kd: f64,
    /// Derivative filter time constant in s, `> 0` when `kd > 0`.
    pub tf_s: f64,
    /// Output limits (output unit).
    pub limits: Limits,
}

impl PidConfig {
    /// Thesis §7.5.3 Chapter 7 gains: Kp 1.65, Ki 562 s⁻¹, Kd 9.5e-4 s, Tf 9.6e-5 s, ±10 V DAC.
    pub const THESIS_CH7: PidConfig = PidConfig {
        kp: 1.65,
        ki: 562.0,
        kd: 9.5e-4,
        tf_s: 9.6e-5,
        limits: Limits::DAC_10V,
    };

    /// Validates the settings and discretises them at `sample_period_s` (s).
    pub fn try_build(&self, sample_period_s: f64) -> Result<Pid, Error> {
        Ok(Pid {
            coeffs: PidCoeffs::try_new(self, sample_period_s)?,
            state: PidState::default(),
            fault: FaultLatch::default(),
        })
    }
}

/// Discrete PID coefficients (see the module documentation for the recursion).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PidCoeffs {
    kp: f64,
    ki_half_t: f64,
    kd: f64,
    df_pole: f64,
    df_gain: f64,
    limits: Limits,
}

impl PidCoeffs {
    /// Tustin coefficients of `config` at `sample_period_s` (s).
    pub fn try_new(config: &PidConfig, sample_period_s: f64) -> Result<Self, Error> {
        let t = check_period(sample_period_s)?;
        let kp = check_range("kp", config.kp, -1e12, 1e12)?;
        let ki = check_range("ki", config.ki, 0.0, 1e12)?;
        let kd = check_range("kd", config.kd, 0.0, 1e12)?;
        let min_tf = if kd > 0.0 { f64::MIN_POSITIVE } else { 0.0 };
        let tf = check_range("tf_s", config.tf_s, min_tf, 1e6)?;
        Ok(PidCoeffs {
            kp,
            ki_half_t: ki * t / 2.0,
            kd,
            df_pole: (2.0 * tf - t) / (2.0 * tf + t),
            df_gain: 2.0 / (2.0 * tf + t),
            limits: config.limits,
        })
    }
}

/// A linear state-space realisation `(A, B, C, D)` of a block (valid while it is unsaturated),
/// for closed-loop analysis off the tick.
pub type Realization<const N: usize> = (
    nalgebra::SMatrix<f64, N, N>,
    nalgebra::SMatrix<f64, N, 1>,
    nalgebra::SMatrix<f64, 1, N>,
    f64,
);

impl PidCoeffs {
    /// The discrete PID as `x⁺ = A x + B e`, `u = C x + D e` with `x = [integral, filtered
    /// derivative, previous error]` (unsaturated).
    pub fn realization(&self) -> Realization<3> {
        let (k, a, b, kd) = (self.ki_half_t, self.df_pole, self.df_gain, self.kd);
        (
            nalgebra::SMatrix::<f64, 3, 3>::new(1.0, 0.0, k, 0.0, a, -b, 0.0, 0.0, 0.0),
            nalgebra::SMatrix::<f64, 3, 1>::new(k, b, 1.0),
            nalgebra::SMatrix::<f64, 1, 3>::new(1.0, kd * a, k - kd * b),
            self.kp + kd * b + k,
        )
    }
}

/// PID state: previous error, integrator (output unit), filtered error derivative (unit/s).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PidState {
    e_prev: f64,
    integral: f64,
    deriv: f64,
}

/// PID controller, thesis eq 7-8. Input: error `r − y`; output: clamped control.
#[derive(Debug, Clone)]
pub struct Pid {
    coeffs: PidCoeffs,
    state: PidState,
    fault: FaultLatch,
}

impl Pid {
    /// Replaces the gains without a bump in the output (the integrator absorbs the change of
    /// the proportional and derivative terms at the last error).
    pub fn set_coeffs(&mut self, new: PidCoeffs) {
        let s = &mut self.state;
        let old = &self.coeffs;
        let old_pd = old.kp * s.e_prev + old.kd * s.deriv;
        let new_pd = new.kp * s.e_prev + new.kd * s.deriv;
        s.integral += old_pd - new_pd;
        self.coeffs = new;
    }

    /// The coefficients in use.
    pub fn coeffs(&self) -> &PidCoeffs {
        &self.coeffs
    }

    /// The integrator's contribution to the output (output unit).
    pub fn integral(&self) -> f64 {
        self.state.integral
    }
}

impl Block for Pid {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, e: f64) -> f64 {
        let c = &self.coeffs;
        let s = &mut self.state;
        let deriv = c.df_pole * s.deriv + c.df_gain * (e - s.e_prev);
        let pd = c.kp * e + c.kd * deriv;
        let integral = s.integral + c.ki_half_t * (e + s.e_prev);
        let unclamped = pd + integral;
        let winding_up = (unclamped > c.limits.max() && integral > s.integral)
            || (unclamped < c.limits.min() && integral < s.integral);
        if !winding_up {
            s.integral = integral;
        }
        s.deriv = flush(deriv);
        s.e_prev = e;
        let u = pd + s.integral;
        if self.fault.check(u) {
            return 0.0;
        }
        c.limits.clamp(u)
    }

    fn reset(&mut self) {
        self.state = PidState::default();
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: f64 = 1.0 / 199_600.0;

    fn unlimited(kp: f64, ki: f64, kd: f64, tf_s: f64) -> Pid {
        PidConfig {
            kp,
            ki,
            kd,
            tf_s,
            limits: Limits::UNLIMITED,
        }
        .try_build(T)
        .unwrap()
    }

    /// Unit step in the error: u[k] = Kp + Ki·T·(k + ½) + Kd·2/(2Tf+T)·α^k, α = (2Tf−T)/(2Tf+T),
    /// derived by hand from the Tustin map of eq 7-8. Tolerance 1e-12 relative.
    #[test]
    fn step_response_matches_closed_form() {
        let (kp, ki, kd, tf) = (1.65, 562.0, 9.5e-4, 9.6e-5);
        let mut pid = unlimited(kp, ki, kd, tf);
        let alpha = (2.0 * tf - T) / (2.0 * tf + T);
        for k in 0..5000 {
            let kf = k as f64;
            let expected = kp + ki * T * (kf + 0.5) + kd * 2.0 / (2.0 * tf + T) * alpha.powi(k);
            let u = pid.update(1.0);
            assert!(
                (u - expected).abs() <= 1e-12 * expected.abs(),
                "k={k}: {u} vs {expected}"
            );
        }
    }

    /// Unit ramp e = t: u = Kp·t + Ki·t²/2 + Kd·(1 − α^k) exactly (trapezoid is exact on a
    /// ramp; the continuous answer is Kd·(1 − e^{−t/Tf}) for the last term).
    #[test]
    fn ramp_response_matches_closed_form() {
        let (kp, ki, kd, tf) = (1.65, 562.0, 9.5e-4, 9.6e-5);
        let mut pid = unlimited(kp, ki, kd, tf);
        let alpha = (2.0 * tf - T) / (2.0 * tf + T);
        for k in 0..5000 {
            let t = k as f64 * T;
            let expected = kp * t + ki * t * t / 2.0 + kd * (1.0 - alpha.powi(k));
            let u = pid.update(t);
            assert!(
                (u - expected).abs() <= 1e-12 * expected.abs().max(1e-9),
                "k={k}"
            );
            // And the derivative term tracks its continuous-time counterpart to O(T²/Tf²).
            let continuous = kd * (1.0 - libm::exp(-t / tf));
            let discrete = kd * (1.0 - alpha.powi(k));
            assert!((discrete - continuous).abs() <= kd * 1e-3);
        }
    }

    #[test]
    fn integrator_holds_while_saturated() {
        let mut pid = PidConfig {
            kp: 1.0,
            ki: 1000.0,
            kd: 0.0,
            tf_s: 0.0,
            limits: Limits::try_new(-1.0, 1.0).unwrap(),
        }
        .try_build(1e-3)
        .unwrap();
        for _ in 0..10_000 {
            assert!(pid.update(5.0) <= 1.0);
        }
        // Without anti-windup the integrator would hold ≈ 5·1000·10 s; it stopped near the limit.
        assert!(pid.integral() < 1.0 + 5.0, "integral {}", pid.integral());
        // Reversing the error leaves saturation at once instead of after a long unwinding.
        let u = pid.update(-0.5);
        assert!(u < 1.0, "u = {u}");
    }

    #[test]
    fn gain_change_is_bumpless() {
        let mut pid = unlimited(1.65, 562.0, 9.5e-4, 9.6e-5);
        for _ in 0..1000 {
            pid.update(0.01);
        }
        let before = pid.update(0.01);
        let faster = PidCoeffs::try_new(
            &PidConfig {
                kp: 3.3,
                ki: 1124.0,
                kd: 1.9e-3,
                tf_s: 9.6e-5,
                limits: Limits::UNLIMITED,
            },
            T,
        )
        .unwrap();
        pid.set_coeffs(faster);
        let after = pid.update(0.01);
        // Only the new integral increment Ki·T·e separates the two samples (plus the decaying
        // derivative, < 1e-12 here).
        let increment = 1124.0 * T * 0.01;
        assert!(
            (after - before - increment).abs() < 1e-9,
            "jump {}",
            after - before
        );
    }

    #[test]
    fn realization_matches_the_running_block() {
        let mut pid = unlimited(1.65, 562.0, 9.5e-4, 9.6e-5);
        let (a, b, c, d) = pid.coeffs().realization();
        let mut x = nalgebra::SMatrix::<f64, 3, 1>::zeros();
        for k in 0..3000 {
            let e = libm::sin(k as f64 * 0.013) + 0.3 * libm::cos(k as f64 * 0.7);
            let want = (c * x)[0] + d * e;
            x = a * x + b * e;
            let got = pid.update(e);
            assert!(
                (got - want).abs() < 1e-11 * (1.0 + want.abs()),
                "k={k}: {got} vs {want}"
            );
        }
    }

    #[test]
    fn rejects_bad_config() {
        let bad = PidConfig {
            tf_s: 0.0,
            ..PidConfig::THESIS_CH7
        };
        assert!(matches!(
            bad.try_build(T),
            Err(Error::OutOfRange { param: "tf_s", .. })
        ));
        assert!(matches!(
            PidConfig::THESIS_CH7.try_build(0.0),
            Err(Error::OutOfRange {
                param: "sample_period_s",
                ..
            })
        ));
        assert!(matches!(
            PidConfig {
                ki: f64::NAN,
                ..PidConfig::THESIS_CH7
            }
            .try_build(T),
            Err(Error::NotFinite { param: "ki" })
        ));
    }
}
