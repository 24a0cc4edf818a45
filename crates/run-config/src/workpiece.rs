//! Freeform machining on the plant side (thesis Ch. 8): the part on the spindle — the exact
//! spindle angle with its drift and step, the encoder count, the cutting force of the surface
//! being cut — along one [`SpiralCut`], which the controller's surface reference follows too.

use crate::surface::LoadedSurface;
use crate::Machining;
use servo_core::surface::Surface;
use servo_core::{Encoder, Spiral};
use std::f64::consts::TAU;

/// A surface cut along the facing spiral: the design height under the tool at each unwrapped
/// spindle angle (what the plant cuts, the controller follows and the form is judged against).
#[derive(Debug, Clone)]
pub struct SpiralCut {
    surface: LoadedSurface,
    spiral: Spiral,
}

impl SpiralCut {
    /// `surface` along the spiral of `m`.
    pub fn new(m: &Machining, surface: LoadedSurface) -> Self {
        SpiralCut {
            surface,
            spiral: m.spiral(),
        }
    }

    /// X radius in m at the unwrapped spindle angle `theta_rad`.
    #[inline]
    pub fn radius_m(&self, theta_rad: f64) -> f64 {
        self.spiral.radius_m(theta_rad)
    }

    /// Design height in m under the tool at spindle angle `theta_rad`.
    #[inline]
    pub fn height_m(&self, theta_rad: f64) -> f64 {
        self.surface.depth_m(self.radius_m(theta_rad), theta_rad)
    }

    /// The error the tool's setting (`[centre height, X offset]`, m) leaves on the part at
    /// spindle angle `theta_rad`, m toward the tool: a prescription's geometry
    /// ([`optics::toolpath::ToolPath::setting_error_m`]), 0 for every other surface.
    pub fn setting_error_m(&self, theta_rad: f64, setting_m: [f64; 2]) -> f64 {
        match &self.surface {
            LoadedSurface::Prescription(p) if setting_m != [0.0; 2] => {
                let e = p.setting_error_m(
                    self.radius_m(theta_rad),
                    theta_rad,
                    setting_m[0],
                    setting_m[1],
                );
                if e.is_finite() {
                    e
                } else {
                    0.0
                }
            }
            _ => 0.0,
        }
    }

    /// The cut path's height above the design's at spindle angle `theta_rad`, m: a
    /// prescription's `[compensation]`, 0 for every other surface (add it to `tool − path`
    /// for the part against the design).
    pub fn compensation_m(&self, theta_rad: f64) -> f64 {
        match &self.surface {
            LoadedSurface::Prescription(p) => {
                let r = self.radius_m(theta_rad);
                p.compensation_m(r * libm::cos(theta_rad), r * libm::sin(theta_rad))
            }
            _ => 0.0,
        }
    }
}

/// The spindle's angle over time: the configured speed with its slow sinusoidal drift and its
/// step (`scenario.spindle_drift_*`, `scenario.spindle_step_*`), from angle 0 at time 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpindleMotion {
    rad_per_s: f64,
    drift_fraction: f64,
    drift_period_s: f64,
    step_fraction: f64,
    step_time_s: f64,
}

impl SpindleMotion {
    /// The spindle of `m`.
    pub fn of(m: &Machining) -> Self {
        SpindleMotion {
            rad_per_s: m.rad_per_s(),
            drift_fraction: m.spindle_drift_fraction,
            drift_period_s: m.spindle_drift_period_s,
            step_fraction: m.spindle_step_fraction,
            step_time_s: m.spindle_step_time_s,
        }
    }

    /// The unwrapped angle in rad at `t_s` seconds: `ω₀·t` plus [`SpindleMotion::departure_rad`].
    #[inline]
    pub fn angle_rad(&self, t_s: f64) -> f64 {
        self.rad_per_s * t_s + self.departure_rad(t_s)
    }

    /// How far in rad the spindle is ahead of one turning at exactly the configured speed `ω₀`
    /// at `t_s` seconds: the speed `ω₀(1 + a·sin(2πt/T) + s·[t > tₛ])` integrated,
    /// `ω₀(a·T/2π·(1 − cos(2πt/T)) + s·max(t − tₛ, 0))`.
    #[inline]
    pub fn departure_rad(&self, t_s: f64) -> f64 {
        let mut seconds = 0.0;
        if self.drift_fraction != 0.0 {
            let w = TAU / self.drift_period_s;
            seconds += self.drift_fraction * (1.0 - libm::cos(w * t_s)) / w;
        }
        if self.step_fraction != 0.0 && t_s > self.step_time_s {
            seconds += self.step_fraction * (t_s - self.step_time_s);
        }
        self.rad_per_s * seconds
    }
}

/// The plant side: the part on a spindle turning at the configured speed (with its drift and
/// step) from angle 0, cut along the spiral.
#[derive(Debug, Clone)]
pub struct Workpiece {
    cut: SpiralCut,
    rad_per_tick: f64,
    period_s: f64,
    motion: SpindleMotion,
    encoder: Encoder,
    /// Force per metre of depth of cut, N/m (specific thrust × feed).
    force_per_depth_n_per_m: f64,
    peak_m: f64,
    finish_depth_m: Option<f64>,
}

impl Workpiece {
    /// The workpiece of `m` at servo period `period_s` (s).
    pub fn new(m: &Machining, surface: LoadedSurface, period_s: f64) -> Self {
        Workpiece {
            peak_m: surface.peak_m(),
            cut: SpiralCut::new(m, surface),
            rad_per_tick: m.rad_per_s() * period_s,
            period_s,
            motion: SpindleMotion::of(m),
            encoder: Encoder {
                pulses_per_rev: m.pulses_per_rev,
            },
            force_per_depth_n_per_m: plant_sim::cutting::thrust_force_n(
                m.specific_thrust_n_per_m2,
                m.feed_m_per_rev,
                1.0,
            ),
            finish_depth_m: m.finish_depth_m,
        }
    }

    /// Spindle angle in rad at the start of tick `k` (unwrapped).
    #[inline]
    pub fn angle_rad(&self, k: u64) -> f64 {
        k as f64 * self.rad_per_tick + self.motion.departure_rad(k as f64 * self.period_s)
    }

    /// The encoder count at the start of tick `k`.
    #[inline]
    pub fn encoder_count(&self, k: u64) -> u64 {
        self.encoder.count_at(self.angle_rad(k))
    }

    /// Cutting force on the tool in N during tick `k` (positive away from the part): the chip
    /// area (feed × the depth of cut at the tool's design position) times the specific thrust
    /// (a known disturbance, as the thesis applied it in §5.7.5; the few-nm deflection's effect
    /// on the chip is neglected).
    #[inline]
    pub fn cutting_force_n(&self, k: u64) -> f64 {
        let depth = match self.finish_depth_m {
            Some(d) => d,
            None => (self.peak_m - self.cut.height_m(self.angle_rad(k))).max(0.0),
        };
        self.force_per_depth_n_per_m * depth
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drifting() -> Machining {
        Machining {
            spindle_rpm: 600.0,
            spindle_drift_fraction: 0.01,
            spindle_drift_period_s: 0.5,
            spindle_step_fraction: -0.02,
            spindle_step_time_s: 0.3,
            ..Machining::default()
        }
    }

    /// The angle is the speed `ω₀(1 + a·sin(2πt/T) + s·[t > tₛ])` integrated: against the
    /// trapezoidal rule at 1 µs steps (error ~1e-13 rad here).
    #[test]
    fn the_angle_integrates_the_drifting_and_stepped_speed() {
        let m = drifting();
        let motion = SpindleMotion::of(&m);
        let speed = |t: f64| {
            let step = if t > m.spindle_step_time_s {
                m.spindle_step_fraction
            } else {
                0.0
            };
            m.rad_per_s()
                * (1.0
                    + m.spindle_drift_fraction * libm::sin(TAU * t / m.spindle_drift_period_s)
                    + step)
        };
        let dt = 1e-6;
        let mut integral = 0.0;
        for k in 0..1_000_000u32 {
            let t = f64::from(k) * dt;
            integral += 0.5 * (speed(t) + speed(t + dt)) * dt;
            if (k + 1) % 100_000 == 0 {
                let t_end = f64::from(k + 1) * dt;
                // The step's own half-step of the rule: at most ω₀·|s|·dt/2.
                let tol = 1e-9 + m.rad_per_s() * m.spindle_step_fraction.abs() * dt;
                let got = motion.angle_rad(t_end);
                assert!(
                    (got - integral).abs() < tol,
                    "t = {t_end}: {got} vs {integral}"
                );
            }
        }
        // Without drift or step, the configured speed exactly.
        let steady = SpindleMotion::of(&Machining::default());
        assert_eq!(
            steady.angle_rad(2.5),
            Machining::default().rad_per_s() * 2.5
        );
    }

    /// After a −2 % step a revolution takes 1/0.98 of the nominal time: the encoder's counts
    /// per revolution arrive that much later.
    #[test]
    fn a_slower_spindle_turns_slower() {
        let m = Machining {
            spindle_drift_fraction: 0.0,
            ..drifting()
        };
        let motion = SpindleMotion::of(&m);
        let nominal = 60.0 / m.spindle_rpm;
        let start = 1.0;
        let turned = motion.angle_rad(start + nominal / 0.98) - motion.angle_rad(start);
        assert!((turned - TAU).abs() < 1e-12, "{turned}");
    }
}
