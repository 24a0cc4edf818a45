//! The matrix exponential and exact discretisation: zero-order hold, the delayed hold whose
//! input switches inside the period (DESIGN.md, "Time and delay"), and Tustin.

use crate::state_space::{LtiError, StateSpace};
use nalgebra::DMatrix;

/// Matrix exponential `e^A` by scaling and squaring with the degree-13 Padé approximant
/// (Higham 2005, "The scaling and squaring method for the matrix exponential revisited").
pub fn expm(a: &DMatrix<f64>) -> DMatrix<f64> {
    const B: [f64; 14] = [
        64764752532480000.0,
        32382376266240000.0,
        7771770303897600.0,
        1187353796428800.0,
        129060195264000.0,
        10559470521600.0,
        670442572800.0,
        33522128640.0,
        1323241920.0,
        40840800.0,
        960960.0,
        16380.0,
        182.0,
        1.0,
    ];
    const THETA13: f64 = 5.371920351148152;
    let n = a.nrows();
    let norm1 = (0..n).map(|j| a.column(j).abs().sum()).fold(0.0, f64::max);
    let s = if norm1 > THETA13 {
        libm::log2(norm1 / THETA13).ceil() as i32
    } else {
        0
    };
    let a = a / 2f64.powi(s);
    let id = DMatrix::<f64>::identity(n, n);
    let a2 = &a * &a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let u_inner = &a6 * (&a6 * B[13] + &a4 * B[11] + &a2 * B[9])
        + &a6 * B[7]
        + &a4 * B[5]
        + &a2 * B[3]
        + &id * B[1];
    let u = &a * u_inner;
    let v = &a6 * (&a6 * B[12] + &a4 * B[10] + &a2 * B[8])
        + &a6 * B[6]
        + &a4 * B[4]
        + &a2 * B[2]
        + &id * B[0];
    let mut r = (&v - &u)
        .lu()
        .solve(&(&v + &u))
        .expect("Padé denominator is nonsingular for ‖A‖ ≤ θ13");
    for _ in 0..s {
        r = &r * &r;
    }
    r
}

/// Tustin (bilinear) discretisation at period `period_s`, pre-warped at `prewarp_hz` if given:
/// `H_d(e^{jωT}) = H(jK·tan(ωT/2))` with `K = 2/T`, or `K = ω0/tan(ω0T/2)` so the responses
/// agree exactly at `f0`.
pub fn c2d_tustin(
    sys: &StateSpace,
    period_s: f64,
    prewarp_hz: Option<f64>,
) -> Result<StateSpace, LtiError> {
    let k = match prewarp_hz {
        Some(f0) => {
            let w0 = 2.0 * std::f64::consts::PI * f0;
            w0 / libm::tan(w0 * period_s / 2.0)
        }
        None => 2.0 / period_s,
    };
    let h = 2.0 / k; // the equivalent step
    let n = sys.nx();
    let id = DMatrix::<f64>::identity(n, n);
    let m = (&id - &sys.a * (h / 2.0))
        .try_inverse()
        .ok_or(LtiError::Argument("c2d_tustin: I − A·T/2 is singular"))?;
    Ok(StateSpace {
        a: &m * (&id + &sys.a * (h / 2.0)),
        b: &m * &sys.b * h,
        c: &sys.c * &m,
        d: &sys.d + &sys.c * &m * &sys.b * (h / 2.0),
    })
}

/// `(e^{A h}, ∫₀ʰ e^{A s} ds · B)`: the exact response over `h` seconds to an input held
/// constant, from one exponential of the block matrix `[[A, B], [0, 0]]·h`.
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (n, m) = (a.nrows(), b.ncols());
    let mut big = DMatrix::<f64>::zeros(n + m, n + m);
    big.view_mut((0, 0), (n, n)).copy_from(&(a * h));
    big.view_mut((0, n), (n, m)).copy_from(&(b * h));
    let e = expm(&big);
    (
        e.view((0, 0), (n, n)).into_owned(),
        e.view((0, n), (n, m)).into_owned(),
    )
}

/// Exact discretisation over one period `T` of an input that switches inside the period: the
/// previous sample's value acts for the first `delay_s`, the new one for the rest.
///
/// `x[k+1] = phi·x[k] + gamma_prev·u[k−1] + gamma_now·u[k]`
#[derive(Debug, Clone, PartialEq)]
pub struct DelayedZoh {
    /// `e^{A T}`.
    pub phi: DMatrix<f64>,
    /// Effect of the input held from the previous tick (acts for `delay_s`).
    pub gamma_prev: DMatrix<f64>,
    /// Effect of this tick's input (acts for `T − delay_s`).
    pub gamma_now: DMatrix<f64>,
}

impl DelayedZoh {
    /// Discretises `(a, b)` at `period_s` with the input arriving `delay_s` ∈ [0, period_s]
    /// after the tick (a delay longer than a period is handled by delaying whole samples first).
    pub fn new(
        a: &DMatrix<f64>,
        b: &DMatrix<f64>,
        period_s: f64,
        delay_s: f64,
    ) -> Result<Self, LtiError> {
        if !(period_s > 0.0 && period_s.is_finite()) {
            return Err(LtiError::Argument("period_s must be finite and > 0"));
        }
        if !(0.0..=period_s).contains(&delay_s) {
            return Err(LtiError::Argument("delay_s must lie in [0, period_s]"));
        }
        let (phi_late, gamma_now) = zoh(a, b, period_s - delay_s);
        let (phi_early, gamma_early) = zoh(a, b, delay_s);
        Ok(DelayedZoh {
            phi: &phi_late * phi_early,
            gamma_prev: &phi_late * gamma_early,
            gamma_now,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use num_complex::Complex64;
    use std::f64::consts::PI;

    /// e^{At} of a damped oscillator against its closed form. Each squaring step can double the
    /// rounding error, so the bound is 1e-13·2^s relative (s = squarings, 13 at t = 3 s).
    #[test]
    fn expm_of_damped_oscillator_matches_closed_form() {
        let (wn, zeta) = (2.0 * PI * 82.0, 0.01);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -wn * wn, -2.0 * zeta * wn]);
        for t in [1e-6, 5e-6, 1e-3, 0.1, 3.0] {
            let e = expm(&(&a * t));
            let wd = wn * (1.0 - zeta * zeta).sqrt();
            let (s, c, ex) = (
                libm::sin(wd * t),
                libm::cos(wd * t),
                libm::exp(-zeta * wn * t),
            );
            let want = [
                ex * (c + zeta * wn / wd * s),
                ex * s / wd,
                -ex * wn * wn / wd * s,
                ex * (c - zeta * wn / wd * s),
            ];
            let got = [e[(0, 0)], e[(0, 1)], e[(1, 0)], e[(1, 1)]];
            let norm1 = (&a * t).abs().row_sum().max(); // ‖At‖₁: largest column sum
            let squarings = libm::log2(norm1 / 5.37).ceil().max(0.0);
            // Entries differ in scale by ωn²: compare each against its own natural scale.
            let natural = [1.0, 1.0 / wd, wn * wn / wd, 1.0];
            for ((g, w), s) in got.iter().zip(want).zip(natural) {
                let tol = 1e-13 * libm::pow(2f64, squarings) * s;
                assert!((g - w).abs() < tol, "t={t}: {g} vs {w}");
            }
        }
    }

    /// A pure integrator ẋ = u: Φ = 1, Γ = h; with a delay d the held old input acts for d.
    #[test]
    fn delayed_zoh_of_integrator() {
        let a = DMatrix::from_element(1, 1, 0.0);
        let b = DMatrix::from_element(1, 1, 1.0);
        let z = DelayedZoh::new(&a, &b, 5e-6, 3.159e-6).unwrap();
        assert!((z.phi[(0, 0)] - 1.0).abs() < 1e-15);
        assert!((z.gamma_prev[(0, 0)] - 3.159e-6).abs() < 1e-18);
        assert!((z.gamma_now[(0, 0)] - (5e-6 - 3.159e-6)).abs() < 1e-18);
    }

    /// First-order lag ẋ = −a x + a u: the delayed ZOH terms have closed forms.
    #[test]
    fn delayed_zoh_of_first_order_lag() {
        let p = 2.0 * PI * 10e3;
        let (t, d) = (1.0 / 199_600.0, 3.159e-6);
        let z = DelayedZoh::new(
            &DMatrix::from_element(1, 1, -p),
            &DMatrix::from_element(1, 1, p),
            t,
            d,
        )
        .unwrap();
        let phi = libm::exp(-p * t);
        let now = 1.0 - libm::exp(-p * (t - d));
        let prev = libm::exp(-p * (t - d)) * (1.0 - libm::exp(-p * d));
        assert!((z.phi[(0, 0)] - phi).abs() < 1e-14);
        assert!((z.gamma_now[(0, 0)] - now).abs() < 1e-14);
        assert!((z.gamma_prev[(0, 0)] - prev).abs() < 1e-14);
    }

    /// c2d by ZOH of a mass-spring-damper puts its poles at e^{sT} (the known discrete poles).
    #[test]
    fn zoh_poles_of_mass_spring_damper() {
        let (m, c, k) = (0.175, 2.28, 21965.0);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -k / m, -c / m]);
        let t = 1.0 / 20_000.0;
        let (phi, _) = zoh(&a, &DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / m]), t);
        let zeta = c / (2.0 * (k * m).sqrt());
        let wn = (k / m).sqrt();
        let s = Complex64::new(-zeta * wn, wn * (1.0 - zeta * zeta).sqrt());
        let want = (s * t).exp();
        let disc = StateSpace::new(
            phi,
            DMatrix::zeros(2, 1),
            DMatrix::zeros(1, 2),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let got = disc.poles().into_iter().find(|p| p.im > 0.0).unwrap();
        assert!((got - want).norm() < 1e-12, "{got} vs {want}");
    }

    /// Tustin maps H(s) to H_d(z) exactly along the warped frequency axis; pre-warped, exactly
    /// at f0 too.
    #[test]
    fn tustin_frequency_mapping() {
        let (m, c, k) = (0.175, 2.28, 21965.0);
        let sys = StateSpace::new(
            DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -k / m, -c / m]),
            DMatrix::from_row_slice(2, 1, &[0.0, 1.0 / m]),
            DMatrix::from_row_slice(1, 2, &[1.0, 0.0]),
            DMatrix::zeros(1, 1),
        )
        .unwrap();
        let t = 1.0 / 20_000.0;
        for pre in [None, Some(56.4)] {
            let d = c2d_tustin(&sys, t, pre).unwrap();
            let kk = pre.map_or(2.0 / t, |f0: f64| 2.0 * PI * f0 / libm::tan(PI * f0 * t));
            for f in [1.0, 56.4, 300.0, 3000.0, 9000.0] {
                let w_analog = kk * libm::tan(PI * f * t);
                let want = sys.freq_response(w_analog).unwrap()[(0, 0)];
                let got = d.freq_response_discrete(f, t).unwrap()[(0, 0)];
                // Near Nyquist the response is ~100 dB below DC and forms by cancellation
                // between the feed-through and state terms: 1e-9 relative is the precision.
                assert!(
                    (got - want).norm() < 1e-9 * want.norm(),
                    "{pre:?} {f}: rel {:e}",
                    (got - want).norm() / want.norm()
                );
            }
            if let Some(f0) = pre {
                let exact = sys.freq_response_at(f0, 0, 0).unwrap();
                let got = d.freq_response_discrete(f0, t).unwrap()[(0, 0)];
                assert!((got - exact).norm() < 1e-10 * exact.norm());
            }
        }
    }
}
