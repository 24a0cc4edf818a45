//! The stage's transfer functions from mechanical impedances (force per displacement, N/m,
//! complex): node equations in the frequency domain, thesis eq 5-4..5-7 without their typos.
//! Independent of the state-space matrices, so each checks the other. An extra impedance at
//! the coil carrier m2 models what a controller adds (eq 7-9, Table 7-1).

use crate::params::StageParams;
use num_complex::Complex64 as C;
use std::f64::consts::PI;

/// Impedances of `p` at one frequency.
#[derive(Debug, Clone, Copy)]
pub struct Impedances {
    s: C,
    k1: C,
    k2: C,
    k3: C,
    k5: C,
    p: StageParams,
}

/// Mass `m` hanging on a spring-damper `(k, c)`, seen from the attachment point.
fn hanging(m: f64, k: f64, c: f64, s: C) -> C {
    let kc = k + c * s;
    kc * m * s * s / (m * s * s + kc)
}

impl Impedances {
    /// At `f_hz` (s = j2πf).
    pub fn new(p: &StageParams, f_hz: f64) -> Self {
        let s = C::new(0.0, 2.0 * PI * f_hz);
        Impedances {
            s,
            k1: p.k1_n_per_m + p.c1_n_s_per_m * s,
            k2: p.k2_n_per_m + p.c2_n_s_per_m * s,
            k3: p.k3_n_per_m + p.c3_n_s_per_m * s,
            k5: p.k5_n_per_m + p.c5_n_s_per_m * s,
            p: *p,
        }
    }

    /// The Laplace variable `s = jω`.
    pub fn s(&self) -> C {
        self.s
    }

    fn z1(&self) -> C {
        hanging(self.p.m1_kg, self.p.k1_n_per_m, self.p.c1_n_s_per_m, self.s)
    }

    fn z4(&self) -> C {
        hanging(self.p.m4_kg, self.p.k4_n_per_m, self.p.c4_n_s_per_m, self.s)
    }

    /// m3 between k2 (to m2) and k3 (to the base), seen from m2.
    fn z3(&self) -> C {
        let m3s = self.p.m3_kg * self.s * self.s + self.k3;
        self.k2 * m3s / (m3s + self.k2)
    }

    /// Everything at node m2 except the tool branch, plus `extra`.
    fn rest(&self, extra: C) -> C {
        self.p.m2_kg * self.s * self.s + self.z3() + self.z4() + self.k5 + extra
    }

    /// x1/x2 through the tool shank.
    pub fn tool_over_m2(&self) -> C {
        self.k1 / (self.p.m1_kg * self.s * self.s + self.k1)
    }

    /// x2 per force on m2, with `extra` added at m2 (thesis eq 5-7: 1/Z).
    pub fn x2_per_motor_force(&self, extra: C) -> C {
        1.0 / (self.rest(extra) + self.z1())
    }

    /// x1 per cutting force on m1: m1 on the series of k1 and everything at m2 (+ `extra`).
    pub fn x1_per_cut_force(&self, extra: C) -> C {
        let rest = self.rest(extra);
        1.0 / (self.p.m1_kg * self.s * self.s + self.k1 * rest / (rest + self.k1))
    }

    /// (x1 − xg)/xg for base motion entering through k3 (and k5), open loop.
    pub fn tool_rel_per_base(&self) -> C {
        let s2 = self.s * self.s;
        let zm2 = self.p.m2_kg * s2 + self.z1() + self.z4() + self.k5 + self.k2;
        let x3_per_f3 = 1.0 / (self.p.m3_kg * s2 + self.k3 + self.k2 - self.k2 * self.k2 / zm2);
        let x3 = x3_per_f3 * self.k3;
        let x2_from_m3 = self.k2 * x3 / zm2;
        let x2_from_k5 =
            self.k5 / (zm2 - self.k2 * self.k2 / (self.p.m3_kg * s2 + self.k3 + self.k2));
        (x2_from_m3 + x2_from_k5) * self.tool_over_m2() - 1.0
    }
}
