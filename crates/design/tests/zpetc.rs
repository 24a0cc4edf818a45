//! ZPETC against Tomizuka's defining property: `T·F = B_u(z⁻¹)B_u(z)/B_u(1)²` — exactly 1 for
//! a minimum-phase loop, and real (zero phase) with the closed-form magnitude otherwise.

use design::zpetc::{design, ZpetcDesign};
use lti::spectral::log_space;
use lti::StateSpace;
use num_complex::Complex64;
use std::f64::consts::PI;

const T: f64 = 1.0;

/// `(z − a)(z − b)` expanded, highest power first.
fn quadratic(a: f64, b: f64) -> Vec<f64> {
    vec![1.0, -(a + b), a * b]
}

fn loop_tf(num: &[f64], den: &[f64]) -> StateSpace {
    StateSpace::from_tf(num, den).unwrap()
}

/// `T(e^{jω})·F(e^{jω})` over the band.
fn product(sys: &StateSpace, f: &ZpetcDesign) -> Vec<(f64, Complex64)> {
    log_space(1e-4, 0.49, 300)
        .into_iter()
        .map(|fr| {
            let t = sys.freq_response_discrete(fr, T).unwrap()[(0, 0)];
            (fr, t * f.response(fr, T))
        })
        .collect()
}

#[test]
fn minimum_phase_loop_is_inverted_exactly() {
    // T = 0.5 (z − 0.3) / ((z − 0.9)(z − 0.5)): one tick of delay, zero inside.
    let sys = loop_tf(&[0.5, -0.15], &quadratic(0.9, 0.5));
    let f = design(&sys, T, 4, 0.49, 1e-9).unwrap();
    assert_eq!(f.preview, 1);
    assert!(f.unacceptable_zeros.is_empty());
    for (fr, tf) in product(&sys, &f) {
        assert!((tf - 1.0).norm() < 1e-10, "f = {fr}: T·F = {tf}");
    }
}

#[test]
fn zero_outside_the_circle_gives_zero_phase_with_the_closed_form_gain() {
    // T = k z⁻¹ (1 + 1.5 z⁻¹) / ((1 − 0.8 z⁻¹)(1 − 0.6 z⁻¹)): zero at −1.5.
    let sys = loop_tf(&[0.1, 0.15], &quadratic(0.8, 0.6));
    let f = design(&sys, T, 4, 0.49, 1e-9).unwrap();
    assert_eq!(f.preview, 2); // one tick of delay + one unacceptable zero
    assert_eq!(f.unacceptable_zeros.len(), 1);
    for (fr, tf) in product(&sys, &f) {
        let w = 2.0 * PI * fr;
        let want = (1.0 + 2.25 + 3.0 * libm::cos(w)) / 6.25;
        assert!(tf.im.abs() < 1e-10, "f = {fr}: phase {}", tf.arg());
        assert!(
            (tf.re - want).abs() < 1e-10,
            "f = {fr}: {} vs {want}",
            tf.re
        );
    }
}

#[test]
fn oscillatory_zero_near_nyquist_is_not_inverted() {
    // A sampling zero at −0.9 (inside, but inverting it rings at Nyquist).
    let sys = loop_tf(&[0.05, 0.045], &quadratic(0.7, 0.2));
    let f = design(&sys, T, 4, 0.49, 1e-9).unwrap();
    assert_eq!(f.unacceptable_zeros.len(), 1);
    for (fr, tf) in product(&sys, &f) {
        let want = (1.0 + 0.81 + 1.8 * libm::cos(2.0 * PI * fr)) / 3.61;
        assert!(tf.im.abs() < 1e-10 && (tf.re - want).abs() < 1e-10);
    }
}

#[test]
fn high_rate_loop_needs_sections_and_reduction() {
    // A 200 kHz sampling of a 2 kHz, ζ = 0.5 second-order loop with a slow PI pole-zero pair and
    // 6 fast (100 kHz) real poles: the model is reduced, and T·F stays zero-phase to 1e-6.
    let h = 1.0 / 200e3;
    let z = |s: f64| libm::exp(s * h);
    let wn = 2.0 * PI * 2e3;
    let (re, im) = (-0.5 * wn, wn * 0.75f64.sqrt());
    let pc = (Complex64::new(re * h, im * h)).exp();
    let mut den = vec![1.0, -2.0 * pc.re, pc.norm_sqr()];
    let mut num = vec![1.0, -z(-2.0 * PI * 40.0)];
    den = convolve(&den, &[1.0, -z(-2.0 * PI * 41.0)]);
    for _ in 0..6 {
        den = convolve(&den, &[1.0, -z(-2.0 * PI * 100e3)]);
    }
    num = convolve(&num, &[1.0, 0.2]);
    let sys = loop_tf(&num, &den).scaled(1.0);
    let dc = sys.freq_response_discrete(0.0, h).unwrap()[(0, 0)].re;
    let sys = sys.scaled(1.0 / dc);
    let f = design(&sys, h, 8, 5e3, 1e-4).unwrap();
    assert!(f.order < sys.nx(), "order {}", f.order);
    for fr in log_space(1.0, 2e3, 100) {
        let t = sys.freq_response_discrete(fr, h).unwrap()[(0, 0)];
        let tf = t * f.response(fr, h);
        assert!(
            tf.arg().abs() < 1e-3 && (tf.norm() - 1.0).abs() < 1e-3,
            "{fr} Hz: {tf}"
        );
    }
}

fn convolve(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; a.len() + b.len() - 1];
    for (i, x) in a.iter().enumerate() {
        for (j, y) in b.iter().enumerate() {
            out[i + j] += x * y;
        }
    }
    out
}

/// A slow zero just outside the unit circle: its zero-phase compensation divides by
/// `B_u(1)² = (1 − 1.0005)²` and lifts `|F|` at Nyquist by `|B_u(−1)|²/|B_u(1)|²` = 1.6·10⁷
/// — beyond `MAX_GAIN`, so the design is refused, naming the gain and the zero; the same loop
/// with the zero at −1.5 (harmless) is accepted.
#[test]
fn a_slow_zero_outside_the_circle_is_refused_not_amplified() {
    use design::zpetc::{ZpetcError, MAX_GAIN};
    let den = convolve(&quadratic(0.8, 0.6), &[1.0, -0.5]);
    let slow = loop_tf(&convolve(&[1.0, -1.0005], &[1.0, -0.3]), &den);
    match design(&slow, T, 4, 0.49, 1e-9) {
        Err(ZpetcError::TooLoud { peak, zeros, .. }) => {
            let want = (2.0005f64 / 0.0005).powi(2);
            assert!(peak > MAX_GAIN && peak > 0.1 * want, "{peak:e}");
            assert!(zeros.contains("1.0005"), "{zeros}");
        }
        other => panic!("{other:?}"),
    }
    let harmless = loop_tf(&convolve(&[1.0, 1.5], &[1.0, -0.3]), &den);
    let f = design(&harmless, T, 4, 0.49, 1e-9).unwrap();
    assert!(f.peak_gain(T).0 <= MAX_GAIN);
}
