//! Disturbance observer (thesis Fig 7-4, Fig 7-5 b, eq 7-3..7-5).
//!
//! The inner plant `G1` maps the controller output (V) to the measured inner signal `y1`
//! (acceleration). Inverting it, the input that must have acted is `G1⁻¹·y1`; minus the output
//! that was applied, that is the disturbance `d̂`. Filtered by `Q`, it is added to the outer
//! controller's output `u_c`:
//!
//! ```text
//! u[k] = u_c[k] + (Q·G1⁻¹)(y1)[k] − Q'(u)[k − 1],      Q(z) = z⁻¹·Q'(z)
//! ```
//!
//! `Q·G1⁻¹` must be causal (choose `Q` with at least the relative degree of `G1`). The applied
//! output enters `Q'` one tick late: that is the one-servo-period measurement delay of §7.3.2,
//! and it keeps the loop free of an algebraic loop. With `Q` from eq 7-5 and the reference
//! filter `C1'` of eq 7-4, the loop equals the cascade of Fig 7-5 a (tested).

use crate::block::{Block, FaultLatch};
use crate::limits::Limits;

/// One tick's inputs of the observer.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ObserverInput {
    /// The outer controller's output `u_c` (V).
    pub control: f64,
    /// The measured inner-plant output `y1` (accelerometer unit).
    pub inner: f64,
}

/// Disturbance observer with user filters `QG1inv ≈ Q·G1⁻¹` (on `y1`) and `Q'` (on `u[k−1]`).
///
/// ```
/// use servo_core::{Block, DisturbanceObserver, Iir, IirCoeffs, Limits, ObserverInput};
/// // No compensation: both filters zero.
/// let zero = IirCoeffs::<1>::new(0.0, [0.0], [0.0]);
/// let mut dob = DisturbanceObserver::new(Iir::new(zero), Iir::new(zero), Limits::DAC_10V);
/// assert_eq!(dob.update(ObserverInput { control: 1.5, inner: 3.0 }), 1.5);
/// ```
#[derive(Debug, Clone)]
pub struct DisturbanceObserver<FY, FU> {
    q_g1_inv: FY,
    q_prime: FU,
    limits: Limits,
    u_prev: f64,
    fault: FaultLatch,
}

impl<FY, FU> DisturbanceObserver<FY, FU>
where
    FY: Block<Input = f64, Output = f64>,
    FU: Block<Input = f64, Output = f64>,
{
    /// An observer from its two filters (already built for the servo rate) and output limits.
    pub fn new(q_g1_inv: FY, q_prime: FU, limits: Limits) -> Self {
        DisturbanceObserver {
            q_g1_inv,
            q_prime,
            limits,
            u_prev: 0.0,
            fault: FaultLatch::default(),
        }
    }
}

impl<FY, FU> Block for DisturbanceObserver<FY, FU>
where
    FY: Block<Input = f64, Output = f64>,
    FU: Block<Input = f64, Output = f64>,
{
    type Input = ObserverInput;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: ObserverInput) -> f64 {
        let compensation = self.q_g1_inv.update(x.inner) - self.q_prime.update(self.u_prev);
        let u = x.control + compensation;
        if self.fault.check(u) | self.q_g1_inv.faulted() | self.q_prime.faulted() {
            self.u_prev = 0.0;
            return 0.0;
        }
        let u = self.limits.clamp(u);
        self.u_prev = u;
        u
    }

    fn reset(&mut self) {
        self.q_g1_inv.reset();
        self.q_prime.reset();
        self.u_prev = 0.0;
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set() || self.q_g1_inv.faulted() || self.q_prime.faulted()
    }
}

#[cfg(test)]
mod tests {
    //! Cascade (Fig 7-5 a) versus observer (Fig 7-5 b) on a discrete plant, eq 7-4 and 7-5.
    use super::*;
    use crate::cascade::{AccelCascadeConfig, CascadeInput};
    use crate::iir::{Iir, IirCoeffs};
    use crate::pid::PidConfig;

    /// Polynomials in z⁻¹, lowest power first.
    fn mul(a: &[f64], b: &[f64]) -> [f64; 8] {
        let mut out = [0.0; 8];
        for (i, x) in a.iter().enumerate() {
            for (j, y) in b.iter().enumerate() {
                out[i + j] += x * y;
            }
        }
        out
    }

    fn add(a: [f64; 8], b: [f64; 8]) -> [f64; 8] {
        core::array::from_fn(|i| a[i] + b[i])
    }

    fn scale(a: [f64; 8], k: f64) -> [f64; 8] {
        a.map(|x| x * k)
    }

    /// An `Iir<N>` from numerator and denominator polynomials (den[0] normalised to 1).
    fn iir<const N: usize>(num: &[f64; 8], den: &[f64; 8]) -> Iir<N> {
        assert!(num[N + 1..]
            .iter()
            .chain(&den[N + 1..])
            .all(|&x| x.abs() < 1e-15));
        let n = |x: f64| x / den[0];
        Iir::new(IirCoeffs::new(
            n(num[0]),
            core::array::from_fn(|i| n(num[i + 1])),
            core::array::from_fn(|i| n(den[i + 1])),
        ))
    }

    #[test]
    fn cascade_equals_observer_with_eq_7_4_and_7_5() {
        let t = 1e-4;
        // G1: V → acceleration, strictly proper; G2: acceleration → position.
        let (n1, d1) = ([0.0, 0.8], [1.0, -0.6]);
        let (n2, d2) = ([0.0, 0.3], [1.0, -0.95]);
        let c2 = 2.0; // Ka, with Ha = 1
        let pid_cfg = PidConfig {
            kp: 0.8,
            ki: 50.0,
            kd: 2e-4,
            tf_s: 3e-4,
            limits: Limits::UNLIMITED,
        };
        // The PID's own transfer function (module docs of `pid`): P + I + D over
        // (1 − z⁻¹)(1 − αz⁻¹).
        let alpha = (2.0 * pid_cfg.tf_s - t) / (2.0 * pid_cfg.tf_s + t);
        let beta = 2.0 / (2.0 * pid_cfg.tf_s + t);
        let dc = mul(&[1.0, -1.0], &[1.0, -alpha]);
        let nc = add(
            add(
                scale(dc, pid_cfg.kp),
                scale(mul(&[1.0, 1.0], &[1.0, -alpha]), pid_cfg.ki * t / 2.0),
            ),
            scale(mul(&[1.0, -1.0], &[1.0, -1.0]), pid_cfg.kd * beta),
        );
        let d12c = mul(&mul(&d1, &d2)[..3], &dc[..3]);
        let n12c = mul(&mul(&n1, &n2)[..3], &nc[..3]);
        // Δ = d1·d2·dc·(1 + C2G1 + C3G1G2)
        let delta = add(
            add(d12c, scale(mul(&mul(&n1, &d2)[..3], &dc[..3]), c2)),
            n12c,
        );
        // eq 7-5: Q = −C2G1/(1 + C2G1 + C3G1G2); Q·G1⁻¹ and Q' = z·Q (n1 = 0.8 z⁻¹).
        let q_g1_inv = scale(d12c, -c2);
        let q_prime = scale(mul(&[n1[1]], &mul(&d2, &dc[..3])[..4]), -c2);
        // eq 7-4 with C1 = C3: C1' = C3·(1 + C3G1G2)/(1 + C2G1 + C3G1G2).
        let c1p_num = mul(&nc[..3], &add(d12c, n12c)[..5]);
        let c1p_den = mul(&dc[..3], &delta[..5]);

        let cascade_cfg = AccelCascadeConfig {
            pid: pid_cfg,
            ka: c2,
            limits: Limits::UNLIMITED,
        };
        let mut cascade = cascade_cfg
            .try_build(t, Iir::new(IirCoeffs::<1>::IDENTITY))
            .unwrap();
        let mut pid = pid_cfg.try_build(t).unwrap();
        let mut c1p = iir::<6>(&c1p_num, &c1p_den);
        let mut dob = DisturbanceObserver::new(
            iir::<4>(&q_g1_inv, &delta),
            iir::<4>(&q_prime, &delta),
            Limits::UNLIMITED,
        );
        let plant = || {
            let g1 = iir::<1>(&mul(&n1, &[1.0]), &mul(&d1, &[1.0]));
            let g2 = iir::<1>(&mul(&n2, &[1.0]), &mul(&d2, &[1.0]));
            (g1, g2)
        };
        let (mut g1a, mut g2a) = plant();
        let (mut g1b, mut g2b) = plant();
        let mut seed = 12345u64;
        let mut rnd = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut worst: f64 = 0.0;
        for _ in 0..3000 {
            let (r, d) = (rnd(), 0.3 * rnd());
            // Strictly proper plants: the outputs at k come from the state alone.
            let (y1a, y2a) = (g1a.peek(0.0), g2a.peek(0.0));
            let (y1b, y2b) = (g1b.peek(0.0), g2b.peek(0.0));
            let ua = cascade.update(CascadeInput {
                error: r - y2a,
                accel: y1a,
            });
            let uc = c1p.update(r) + pid.update(-y2b);
            let ub = dob.update(ObserverInput {
                control: uc,
                inner: y1b,
            });
            g2a.update(g1a.update(ua + d));
            g2b.update(g1b.update(ub + d));
            assert!((y1a - y1b).abs() < 1e-9 * (1.0 + y1a.abs()));
            worst = worst.max((y2a - y2b).abs() / (1.0 + y2a.abs()));
        }
        assert!(worst < 1e-9, "largest relative mismatch {worst}");
    }
}
