//! Model-inverse feedforward for a mass-spring-damper stage:
//! `u = (m·r̈ + c·ṙ + k·r) / gain`, the force that moves the stage along the trajectory,
//! converted to the controller's output unit (V) by the actuator gain `H_I·K_T` (N/V).

use crate::block::{Block, FaultLatch};
use crate::error::{check_range, Error};
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
    /// The heavy thesis stage (§5.7.3): 0.175 kg, flexure 21965 N/m and 2.28 N·s/m
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
