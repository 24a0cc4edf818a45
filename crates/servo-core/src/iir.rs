//! IIR filters in transposed direct form II, any order `N` (a biquad is `N = 2`), with
//! bilinear, pre-warped designers for the usual servo shapes and a cascade of sections.
//!
//! ```text
//! H(z) = (b0 + b1 z⁻¹ + … + bN z⁻ᴺ) / (1 + a1 z⁻¹ + … + aN z⁻ᴺ)
//! y = b0·x + s1;  s_i = b_i·x − a_i·y + s_{i+1};  s_N = b_N·x − a_N·y
//! ```

use crate::block::{Block, FaultLatch};
use crate::error::{check_period, check_range, Error};
use crate::math::flush;
use core::f64::consts::PI;

/// Coefficients of an order-`N` IIR filter with `a0 = 1`.
///
/// ```
/// use servo_core::IirCoeffs;
/// let c = IirCoeffs::new(0.5, [0.5], [0.0]); // two-tap moving average
/// assert_eq!(c.dc_gain(), 1.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IirCoeffs<const N: usize> {
    /// Feed-through numerator coefficient b0.
    pub b0: f64,
    /// Numerator coefficients b1..bN.
    pub b: [f64; N],
    /// Denominator coefficients a1..aN (a0 = 1).
    pub a: [f64; N],
}

impl<const N: usize> IirCoeffs<N> {
    /// The identity filter `H(z) = 1`.
    pub const IDENTITY: Self = IirCoeffs {
        b0: 1.0,
        b: [0.0; N],
        a: [0.0; N],
    };

    /// Coefficients from `b0`, `b1..bN`, `a1..aN`.
    pub const fn new(b0: f64, b: [f64; N], a: [f64; N]) -> Self {
        IirCoeffs { b0, b, a }
    }

    /// `H(z = 1)`, the gain at DC.
    pub fn dc_gain(&self) -> f64 {
        let num = self.b0 + self.b.iter().sum::<f64>();
        let den = 1.0 + self.a.iter().sum::<f64>();
        num / den
    }

    /// The filter as `x⁺ = A x + B u`, `y = C x + D u` (the transposed direct form's states).
    pub fn realization(&self) -> crate::pid::Realization<N> {
        let a = nalgebra::SMatrix::<f64, N, N>::from_fn(|i, j| {
            if j == 0 {
                -self.a[i]
            } else if j == i + 1 {
                1.0
            } else {
                0.0
            }
        });
        let b = nalgebra::SMatrix::<f64, N, 1>::from_fn(|i, _| self.b[i] - self.a[i] * self.b0);
        let c = nalgebra::SMatrix::<f64, 1, N>::from_fn(|_, j| if j == 0 { 1.0 } else { 0.0 });
        (a, b, c, self.b0)
    }

    /// Checks that every coefficient is finite.
    pub fn validate(&self) -> Result<Self, Error> {
        let finite = self.b0.is_finite()
            && self.b.iter().all(|x| x.is_finite())
            && self.a.iter().all(|x| x.is_finite());
        if finite {
            Ok(*self)
        } else {
            Err(Error::NotFinite {
                param: "iir coefficients",
            })
        }
    }
}

/// An order-`N` IIR filter (transposed direct form II) with its state.
#[derive(Debug, Clone, Copy)]
pub struct Iir<const N: usize> {
    coeffs: IirCoeffs<N>,
    state: [f64; N],
    fault: FaultLatch,
}

/// A second-order section.
pub type Biquad = Iir<2>;

impl<const N: usize> Iir<N> {
    /// A filter with zero state.
    pub const fn new(coeffs: IirCoeffs<N>) -> Self {
        Iir {
            coeffs,
            state: [0.0; N],
            fault: FaultLatch::CLEAR,
        }
    }

    /// The coefficients in use.
    pub fn coeffs(&self) -> &IirCoeffs<N> {
        &self.coeffs
    }

    /// Replaces the coefficients, keeping the state (for smooth retuning of slow filters).
    pub fn set_coeffs(&mut self, coeffs: IirCoeffs<N>) {
        self.coeffs = coeffs;
    }

    /// Sets the state to that of an input at rest at `x` forever: the next output for `x` is
    /// `dc_gain·x` (a stable filter; an integrator has no such state and keeps its own).
    pub(crate) fn prime(&mut self, x: f64) {
        let c = &self.coeffs;
        let y = c.dc_gain() * x;
        if !y.is_finite() {
            return;
        }
        let mut acc = 0.0;
        for i in (0..N).rev() {
            acc += c.b[i] * x - c.a[i] * y;
            self.state[i] = acc;
        }
    }

    /// The output for input `x` without touching the state (for strictly proper `b0 = 0`
    /// filters this is the next output whatever `x` is).
    #[inline]
    pub fn peek(&self, x: f64) -> f64 {
        self.coeffs.b0 * x + self.state.first().copied().unwrap_or(0.0)
    }
}

impl<const N: usize> Block for Iir<N> {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: f64) -> f64 {
        let c = &self.coeffs;
        let y = self.peek(x);
        for i in 0..N {
            let next = if i + 1 < N { self.state[i + 1] } else { 0.0 };
            self.state[i] = flush(c.b[i] * x - c.a[i] * y + next);
        }
        if self.fault.check(y) {
            return 0.0;
        }
        y
    }

    fn reset(&mut self) {
        self.state = [0.0; N];
        self.fault = FaultLatch::default();
    }

    fn faulted(&self) -> bool {
        self.fault.is_set()
    }
}

/// `M` biquads in series.
///
/// ```
/// use servo_core::{Block, BiquadCascade, BiquadDesign};
/// let lp = BiquadDesign::LowPass { f0_hz: 10e3, q: core::f64::consts::FRAC_1_SQRT_2 }.try_coeffs(1e-5).unwrap();
/// let mut two = BiquadCascade::new([lp, lp]);
/// assert!((two.dc_gain() - 1.0).abs() < 1e-12);
/// let _ = two.update(1.0);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct BiquadCascade<const M: usize> {
    sections: [Biquad; M],
}

impl<const M: usize> BiquadCascade<M> {
    /// A cascade of sections with zero state.
    pub fn new(coeffs: [IirCoeffs<2>; M]) -> Self {
        BiquadCascade {
            sections: coeffs.map(Iir::new),
        }
    }

    /// Product of the sections' DC gains.
    pub fn dc_gain(&self) -> f64 {
        self.sections.iter().map(|s| s.coeffs().dc_gain()).product()
    }

    /// Sets every section's state to that of an input at rest at `x` forever.
    pub(crate) fn prime(&mut self, x: f64) {
        let mut input = x;
        for s in &mut self.sections {
            s.prime(input);
            input *= s.coeffs().dc_gain();
        }
    }
}

impl<const M: usize> Block for BiquadCascade<M> {
    type Input = f64;
    type Output = f64;

    #[inline]
    fn update(&mut self, x: f64) -> f64 {
        self.sections.iter_mut().fold(x, |acc, s| s.update(acc))
    }

    fn reset(&mut self) {
        self.sections.iter_mut().for_each(Block::reset);
    }

    fn faulted(&self) -> bool {
        self.sections.iter().any(Block::faulted)
    }
}

/// Biquad shapes designed from their analog prototypes by the bilinear transform pre-warped at
/// the centre/corner frequency, so the digital response equals the analog one exactly at `f0`
/// (and `H_d(e^{jωT}) = H_a(j·K·tan(ωT/2))` with `K = ω0 / tan(ω0·T/2)` everywhere).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BiquadDesign {
    /// First-order `ω0 / (s + ω0)` (a biquad with `b2 = a2 = 0`).
    FirstOrderLowPass {
        /// Corner frequency in Hz.
        f0_hz: f64,
    },
    /// `ω0² / (s² + (ω0/Q)s + ω0²)`.
    LowPass {
        /// Corner frequency in Hz.
        f0_hz: f64,
        /// Quality factor (0.7071 for Butterworth).
        q: f64,
    },
    /// `s² / (s² + (ω0/Q)s + ω0²)`.
    HighPass {
        /// Corner frequency in Hz.
        f0_hz: f64,
        /// Quality factor.
        q: f64,
    },
    /// `(s² + ω0²) / (s² + (ω0/Q)s + ω0²)`.
    Notch {
        /// Notch frequency in Hz.
        f0_hz: f64,
        /// Quality factor (−3 dB width = f0/Q).
        q: f64,
    },
    /// `(s² + g·(ω0/Q)s + ω0²) / (s² + (ω0/Q)s + ω0²)`, `g = 10^(gain_db/20)`.
    Peak {
        /// Centre frequency in Hz.
        f0_hz: f64,
        /// Quality factor.
        q: f64,
        /// Gain at `f0` in dB (negative for a dip).
        gain_db: f64,
    },
}

impl BiquadDesign {
    /// Analog prototype numerator and denominator `[s², s¹, s⁰]` coefficients, ω0 in rad/s.
    pub fn analog(&self) -> ([f64; 3], [f64; 3]) {
        let (f0, q) = self.f0_q();
        let w0 = 2.0 * PI * f0;
        let den = [1.0, w0 / q, w0 * w0];
        match *self {
            BiquadDesign::FirstOrderLowPass { .. } => ([0.0, 0.0, w0], [0.0, 1.0, w0]),
            BiquadDesign::LowPass { .. } => ([0.0, 0.0, w0 * w0], den),
            BiquadDesign::HighPass { .. } => ([1.0, 0.0, 0.0], den),
            BiquadDesign::Notch { .. } => ([1.0, 0.0, w0 * w0], den),
            BiquadDesign::Peak { gain_db, .. } => (
                [1.0, libm::pow(10.0, gain_db / 20.0) * w0 / q, w0 * w0],
                den,
            ),
        }
    }

    fn f0_q(&self) -> (f64, f64) {
        match *self {
            BiquadDesign::FirstOrderLowPass { f0_hz } => (f0_hz, 1.0),
            BiquadDesign::LowPass { f0_hz, q }
            | BiquadDesign::HighPass { f0_hz, q }
            | BiquadDesign::Notch { f0_hz, q }
            | BiquadDesign::Peak { f0_hz, q, .. } => (f0_hz, q),
        }
    }

    /// The pre-warp constant `K = ω0 / tan(ω0·T/2)` in rad/s that replaces `2/T`.
    pub fn prewarp(&self, sample_period_s: f64) -> f64 {
        let w0 = 2.0 * PI * self.f0_q().0;
        w0 / libm::tan(w0 * sample_period_s / 2.0)
    }

    /// Discrete coefficients at `sample_period_s` (s). `f0` must lie below Nyquist.
    pub fn try_coeffs(&self, sample_period_s: f64) -> Result<IirCoeffs<2>, Error> {
        let t = check_period(sample_period_s)?;
        let (f0, q) = self.f0_q();
        check_range("f0_hz", f0, f64::MIN_POSITIVE, 0.499 / t)?;
        check_range("q", q, 1e-3, 1e4)?;
        if let BiquadDesign::Peak { gain_db, .. } = *self {
            check_range("gain_db", gain_db, -200.0, 200.0)?;
        }
        let (num, den) = self.analog();
        Ok(bilinear(num, den, self.prewarp(t)))
    }
}

/// Bilinear map of `(n0 s² + n1 s + n2)/(d0 s² + d1 s + d2)` with `s = K(1 − z⁻¹)/(1 + z⁻¹)`.
/// A first-order prototype (`n0 = d0 = 0`) maps to `b2 = a2 = 0`: multiplying by
/// `(1 + z⁻¹)²` would add a cancelling pole-zero pair at z = −1 (an undamped Nyquist mode).
fn bilinear(num: [f64; 3], den: [f64; 3], k: f64) -> IirCoeffs<2> {
    let k2 = k * k;
    let first_order = num[0] == 0.0 && den[0] == 0.0;
    let map = |p: [f64; 3]| {
        if first_order {
            [p[1] * k + p[2], p[2] - p[1] * k, 0.0]
        } else {
            [
                p[0] * k2 + p[1] * k + p[2],
                2.0 * (p[2] - p[0] * k2),
                p[0] * k2 - p[1] * k + p[2],
            ]
        }
    };
    let (n, d) = (map(num), map(den));
    IirCoeffs::new(
        n[0] / d[0],
        [n[1] / d[0], n[2] / d[0]],
        [d[1] / d[0], d[2] / d[0]],
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Minimal complex arithmetic for the reference responses.
    #[derive(Clone, Copy)]
    struct C(f64, f64);
    impl C {
        fn mul(self, o: C) -> C {
            C(self.0 * o.0 - self.1 * o.1, self.0 * o.1 + self.1 * o.0)
        }
        fn div(self, o: C) -> C {
            let d = o.0 * o.0 + o.1 * o.1;
            C(
                (self.0 * o.0 + self.1 * o.1) / d,
                (self.1 * o.0 - self.0 * o.1) / d,
            )
        }
        fn abs(self) -> f64 {
            libm::hypot(self.0, self.1)
        }
        fn arg(self) -> f64 {
            libm::atan2(self.1, self.0)
        }
    }

    fn poly(c: &[f64], x: C) -> C {
        c.iter().fold(C(0.0, 0.0), |acc, &k| {
            let m = acc.mul(x);
            C(m.0 + k, m.1)
        })
    }

    /// Digital response from the coefficients, `H(e^{jω})`.
    fn digital(c: &IirCoeffs<2>, w: f64) -> C {
        let zi = C(libm::cos(w), -libm::sin(w)); // z⁻¹
        let num = [c.b[1], c.b[0], c.b0]; // in powers of z⁻¹, highest first
        let den = [c.a[1], c.a[0], 1.0];
        poly(&num, zi).div(poly(&den, zi))
    }

    const T: f64 = 1.0 / 199_600.0;

    fn designs() -> [BiquadDesign; 6] {
        [
            BiquadDesign::LowPass {
                f0_hz: 15e3,
                q: core::f64::consts::FRAC_1_SQRT_2,
            },
            BiquadDesign::HighPass {
                f0_hz: 50.0,
                q: 0.5,
            },
            BiquadDesign::Notch {
                f0_hz: 1600.0,
                q: 5.0,
            },
            BiquadDesign::FirstOrderLowPass { f0_hz: 300.0 },
            BiquadDesign::Peak {
                f0_hz: 7748.0,
                q: 10.0,
                gain_db: -12.0,
            },
            BiquadDesign::Peak {
                f0_hz: 40e3,
                q: 2.0,
                gain_db: 6.0,
            },
        ]
    }

    /// Bilinear with pre-warp is an exact frequency map: H_d(e^{jωT}) = H_a(jK·tan(ωT/2)).
    #[test]
    fn designs_match_analog_prototype_to_1e9() {
        for d in designs() {
            let c = d.try_coeffs(T).unwrap();
            let (num, den) = d.analog();
            let k = d.prewarp(T);
            for i in 1..200 {
                let w = PI * i as f64 / 200.0;
                let s = C(0.0, k * libm::tan(w / 2.0));
                let analog = poly(&num, s).div(poly(&den, s));
                let dig = digital(&c, w);
                let scale = analog.abs().max(1e-6);
                assert!(
                    (dig.0 - analog.0).abs() < 1e-9 * scale
                        && (dig.1 - analog.1).abs() < 1e-9 * scale,
                    "{d:?} at ω={w}"
                );
            }
            // Pre-warped: the analog value at ω0 itself is hit exactly.
            let (f0, _) = d.f0_q();
            let w0 = 2.0 * PI * f0;
            let exact = poly(&num, C(0.0, w0)).div(poly(&den, C(0.0, w0)));
            let dig = digital(&c, w0 * T);
            // Tolerance relative to the unit passband gain (a notch's exact value is zero).
            assert!((dig.abs() - exact.abs()).abs() < 1e-9, "{d:?}");
        }
    }

    /// A first-order design is a true first-order section: no pole (or zero) at z = −1.
    #[test]
    fn first_order_low_pass_has_one_pole() {
        let c = BiquadDesign::FirstOrderLowPass { f0_hz: 300.0 }
            .try_coeffs(T)
            .unwrap();
        assert_eq!((c.b[1], c.a[1]), (0.0, 0.0));
        let pole = -c.a[0];
        assert!((pole - libm::exp(-2.0 * PI * 300.0 * T)).abs() < 1e-4);
        assert!((c.dc_gain() - 1.0).abs() < 1e-12);
    }

    /// The running filter's steady-state sine response equals H(e^{jω}) in magnitude and phase.
    #[test]
    fn time_domain_sine_matches_frequency_response() {
        for d in designs() {
            let c = d.try_coeffs(T).unwrap();
            // Exactly 64 periods in 8192 samples: an exact DFT bin.
            let (n, periods) = (8192usize, 64.0);
            let w = 2.0 * PI * periods / n as f64;
            let mut f = Iir::new(c);
            // Settle long enough for the slowest pole (50 Hz high-pass: τ ≈ 3.2 ms, 1 s ≈ 300 τ).
            for k in 0..200_000 {
                f.update(libm::sin(w * k as f64));
            }
            let (mut re, mut im) = (0.0, 0.0);
            for k in 200_000..200_000 + n {
                let y = f.update(libm::sin(w * k as f64));
                let ph = w * (k - 200_000) as f64;
                re += y * libm::cos(ph);
                im -= y * libm::sin(ph);
            }
            // Input sin(ph + w·200000) has DFT phase w·200000 − π/2.
            let measured = C(2.0 * re / n as f64, 2.0 * im / n as f64);
            let input_phase = w * 200_000.0 - PI / 2.0;
            let h = digital(&c, w);
            let dphase = libm::remainder(measured.arg() - input_phase - h.arg(), 2.0 * PI);
            assert!(
                (measured.abs() - h.abs()).abs() < 1e-9 * h.abs().max(1e-3),
                "{d:?}"
            );
            assert!(dphase.abs() < 1e-7 || h.abs() < 1e-6, "{d:?}: {dphase}");
        }
    }

    #[test]
    fn notch_nulls_and_cascade_multiplies() {
        let c = BiquadDesign::Notch {
            f0_hz: 1600.0,
            q: 5.0,
        }
        .try_coeffs(T)
        .unwrap();
        assert!(digital(&c, 2.0 * PI * 1600.0 * T).abs() < 1e-12);
        let lp = BiquadDesign::LowPass {
            f0_hz: 10e3,
            q: core::f64::consts::FRAC_1_SQRT_2,
        }
        .try_coeffs(T)
        .unwrap();
        let mut cascade = BiquadCascade::new([lp, c]);
        let (mut a, mut b) = (Iir::new(lp), Iir::new(c));
        for k in 0..1000 {
            let x = libm::sin(k as f64 * 0.37) + if k == 3 { 1.0 } else { 0.0 };
            assert_eq!(cascade.update(x), b.update(a.update(x)));
        }
    }

    #[test]
    fn realization_matches_the_running_filter() {
        for d in designs() {
            let co = d.try_coeffs(T).unwrap();
            let (a, b, c, dd) = co.realization();
            let mut x = nalgebra::SMatrix::<f64, 2, 1>::zeros();
            let mut f = Iir::new(co);
            for k in 0..500 {
                let u = libm::sin(k as f64 * 0.05) + if k == 0 { 1.0 } else { 0.0 };
                let want = (c * x)[0] + dd * u;
                x = a * x + b * u;
                assert!((f.update(u) - want).abs() < 1e-12 * (1.0 + want.abs()));
            }
        }
    }

    #[test]
    fn rejects_f0_above_nyquist() {
        let e = BiquadDesign::LowPass {
            f0_hz: 150e3,
            q: 0.7,
        }
        .try_coeffs(T)
        .unwrap_err();
        assert!(matches!(e, Error::OutOfRange { param: "f0_hz", .. }));
    }
}
