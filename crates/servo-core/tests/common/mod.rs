//! One instance of every servo-core block, shared by the integration tests.
#![allow(dead_code, missing_docs)]

use nalgebra::SMatrix;
use servo_core::*;

pub const T: f64 = 1.0 / 199_600.0;
pub const LIMITS: Limits = Limits::DAC_10V;

pub fn pid() -> Pid {
    PidConfig::THESIS_CH7.try_build(T).unwrap()
}

pub fn biquad() -> Biquad {
    Iir::new(
        BiquadDesign::Notch {
            f0_hz: 1600.0,
            q: 5.0,
        }
        .try_coeffs(T)
        .unwrap(),
    )
}

pub fn cascade() -> AccelCascade<BiquadCascade<2>> {
    let lp = BiquadDesign::LowPass {
        f0_hz: 10e3,
        q: core::f64::consts::FRAC_1_SQRT_2,
    }
    .try_coeffs(T)
    .unwrap();
    AccelCascadeConfig {
        pid: PidConfig::THESIS_CH7,
        ka: 4.0,
        limits: LIMITS,
    }
    .try_build(T, BiquadCascade::new([lp, lp]))
    .unwrap()
}

/// A stable 27-state controller with a deterministic pseudo-random realisation.
pub fn state_space_27() -> StateSpace<27, 1, 1> {
    let mut seed = 0x9e3779b97f4a7c15u64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    StateSpaceConfig::<27, 1, 1> {
        a: SMatrix::from_fn(|_, _| rnd() * 0.07),
        b: SMatrix::from_fn(|_, _| rnd()),
        c: SMatrix::from_fn(|_, _| rnd()),
        d: SMatrix::from_fn(|_, _| rnd()),
        limits: LIMITS,
    }
    .try_build(5e-5)
    .unwrap()
}

pub fn observer() -> DisturbanceObserver<Iir<2>, Iir<2>> {
    let q = BiquadDesign::LowPass {
        f0_hz: 2e3,
        q: core::f64::consts::FRAC_1_SQRT_2,
    }
    .try_coeffs(T)
    .unwrap();
    DisturbanceObserver::new(Iir::new(q), Iir::new(q), LIMITS)
}

pub fn delay() -> TransportDelay<8> {
    TransportDelay::try_new(3.159e-6, T).unwrap()
}

pub fn feedforward() -> Feedforward {
    FeedforwardConfig::THESIS_HEAVY.try_build().unwrap()
}
