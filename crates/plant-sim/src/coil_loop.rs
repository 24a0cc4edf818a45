//! The R-L coil with its analog PI current loop, integrated inside a tick (the `coil`
//! current-loop model of the simulator).

use crate::params::{rad, PlantParams};

/// The R-L coil and its analog PI current controller (§4.6.3), integrated by RK4 sub-steps.
/// The PI integral corner cancels the coil pole `R/L`, so the unsaturated loop is first order
/// at `loop_bandwidth_hz`; the amplifier clips at the bus voltage (the integrator then holds)
/// and the reference at the peak current.
#[derive(Debug, Clone)]
pub(crate) struct CoilLoop {
    pub(crate) kp: f64,
    pub(crate) ki: f64,
    pub(crate) r: f64,
    pub(crate) l: f64,
    pub(crate) bus: f64,
    pub(crate) peak: f64,
    pub(crate) gain: f64,
    pub(crate) kt: f64,
    /// Coil current in A and PI integrator output in V.
    pub(crate) i: f64,
    pub(crate) q: f64,
    /// Row giving the coil velocity `v2 − v3` from the state (balanced coordinates).
    pub(crate) velocity_row: Vec<f64>,
    /// Sub-steps before the delay (they use the previous reference).
    pub(crate) before_delay: usize,
}

impl CoilLoop {
    pub(crate) fn new(p: &PlantParams, velocity_row: Vec<f64>, before_delay: usize) -> Self {
        let c = &p.actuator.coil;
        let r = c.resistance_ohm + c.sense_resistance_ohm;
        let kp = c.inductance_h * rad(c.loop_bandwidth_hz);
        CoilLoop {
            kp,
            ki: kp * r / c.inductance_h,
            r,
            l: c.inductance_h,
            bus: c.bus_v,
            peak: c.peak_a,
            gain: p.actuator.current_gain_a_per_v,
            kt: p.actuator.kt_n_per_a,
            i: 0.0,
            q: 0.0,
            velocity_row,
            before_delay,
        }
    }

    /// `(di/dt, dq/dt)` for reference `r` (A) and coil velocity `v` (m/s).
    #[inline]
    fn deriv(&self, i: f64, q: f64, r: f64, v: f64) -> (f64, f64) {
        let e = r - i;
        let raw = self.kp * e + q;
        let volts = raw.clamp(-self.bus, self.bus);
        let winding_up = (raw > self.bus && e > 0.0) || (raw < -self.bus && e < 0.0);
        let dq = if winding_up { 0.0 } else { self.ki * e };
        ((volts - self.r * i - self.kt * v) / self.l, dq)
    }

    /// One RK4 step of `h` s; returns the mean current over it (trapezoid).
    #[inline]
    fn substep(&mut self, h: f64, r: f64, v: f64) -> f64 {
        let (i0, q0) = (self.i, self.q);
        let (a1, b1) = self.deriv(i0, q0, r, v);
        let (a2, b2) = self.deriv(i0 + 0.5 * h * a1, q0 + 0.5 * h * b1, r, v);
        let (a3, b3) = self.deriv(i0 + 0.5 * h * a2, q0 + 0.5 * h * b2, r, v);
        let (a4, b4) = self.deriv(i0 + h * a3, q0 + h * b3, r, v);
        self.i = i0 + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
        self.q = q0 + h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
        0.5 * (i0 + self.i)
    }

    /// Integrates the tick; writes the mean current of each sub-step into `out`.
    pub(crate) fn tick(
        &mut self,
        intervals: &[(f64, f64)],
        u_prev: f64,
        u_now: f64,
        x: &[f64],
        out: &mut [f64],
    ) {
        let v: f64 = self.velocity_row.iter().zip(x).map(|(a, b)| a * b).sum();
        let reference = |u: f64| (self.gain * u).clamp(-self.peak, self.peak);
        let (r_prev, r_now) = (reference(u_prev), reference(u_now));
        for (j, (&(a, b), o)) in intervals.iter().zip(out.iter_mut()).enumerate() {
            let r = if j < self.before_delay { r_prev } else { r_now };
            *o = self.substep(b - a, r, v);
        }
    }
}
