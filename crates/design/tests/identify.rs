//! Grey-box identification on a mass-spring-damper G(s) = 1/(m s² + c s + k) with the thesis
//! stage's numbers (Table 5-2: m1 + m2 = 0.074 kg, k2 = 21965 N/m, c2 = 2.28 N·s/m): a noisy
//! FRF gives back the truth, and the reported 1σ uncertainties cover the actual errors.

use design::identify::fit;
use num_complex::Complex64;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

const TRUTH: [f64; 3] = [0.074, 2.28, 21965.0];

fn response(p: &[f64], freq_hz: &[f64]) -> Vec<Complex64> {
    freq_hz
        .iter()
        .map(|&f| {
            let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            1.0 / (p[0] * s * s + p[1] * s + p[2])
        })
        .collect()
}

/// 200 frequencies, logarithmically spaced from 1 Hz to 1 kHz.
fn one_hz_to_one_khz() -> Vec<f64> {
    (0..200)
        .map(|i| libm::pow(10f64, 3.0 * i as f64 / 199.0))
        .collect()
}

#[test]
fn recovers_mass_damping_and_stiffness_from_a_noisy_frf() {
    let freq_hz = one_hz_to_one_khz();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    let noise = Normal::new(0.0, 0.005).unwrap(); // 0.5 % per component
    let measured: Vec<Complex64> = response(&TRUTH, &freq_hz)
        .into_iter()
        .map(|g| g * Complex64::new(1.0 + noise.sample(&mut rng), noise.sample(&mut rng)))
        .collect();
    let start = [1.5 * TRUTH[0], 0.5 * TRUTH[1], 2.0 * TRUTH[2]];
    let lower = TRUTH.map(|v| v / 10.0);
    let upper = TRUTH.map(|v| v * 10.0);
    let mut model = |p: &[f64]| Ok(response(p, &freq_hz));
    let f = fit(&mut model, &measured, &start, &lower, &upper, 100).unwrap();
    for (i, truth) in TRUTH.iter().enumerate() {
        let err = f.params[i] / truth - 1.0;
        assert!(
            err.abs() < 0.01,
            "parameter {i}: {} ({err:+.2e})",
            f.params[i]
        );
        assert!(
            err.abs() < 4.0 * f.rel_std[i],
            "parameter {i}: error {err:.2e} vs 1σ {:.2e}",
            f.rel_std[i]
        );
    }
    // The least-squares optimum fits the (weighted) data at least as well as the truth does.
    let at_truth = fit(&mut model, &measured, &TRUTH, &lower, &upper, 0).unwrap();
    assert!(f.weighted_fit_percent >= at_truth.weighted_fit_percent - 1e-9);
    assert!(f.fit_percent > 98.0, "fit {} %", f.fit_percent);
    // The right structure leaves white noise: Durbin–Watson about 2 (its spread on 2 × 199
    // differences of white noise is 2/√400 = 0.1).
    assert!(
        (f.durbin_watson - 2.0).abs() < 0.3,
        "d = {}",
        f.durbin_watson
    );
}

#[test]
fn a_structure_the_model_lacks_shows_in_the_residual() {
    // The same noisy stage seen through a mode at 2 kHz, above the 1 kHz band (poles and zeros
    // at 2 kHz, damping 0.01 and 0.02: a phase lead growing to 0.76° at the band's top),
    // fitted with the mass-spring-damper alone: the residual follows the mode's tail, so
    // neighbouring points are alike and the Durbin–Watson statistic falls far below 2.
    let freq_hz = one_hz_to_one_khz();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.001).unwrap();
    let w0 = 2.0 * std::f64::consts::PI * 2000.0;
    let measured: Vec<Complex64> = response(&TRUTH, &freq_hz)
        .into_iter()
        .zip(&freq_hz)
        .map(|(g, &f)| {
            let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            let mode = (s * s + 0.04 * w0 * s + w0 * w0) / (s * s + 0.02 * w0 * s + w0 * w0);
            g * mode * Complex64::new(1.0 + noise.sample(&mut rng), noise.sample(&mut rng))
        })
        .collect();
    let lower = TRUTH.map(|v| v / 10.0);
    let upper = TRUTH.map(|v| v * 10.0);
    let mut model = |p: &[f64]| Ok(response(p, &freq_hz));
    let f = fit(&mut model, &measured, &TRUTH, &lower, &upper, 100).unwrap();
    assert!(f.durbin_watson < 1.0, "d = {}", f.durbin_watson);
}

#[test]
fn a_bound_holds_the_estimate() {
    let freq_hz: Vec<f64> = (0..50)
        .map(|i| libm::pow(10f64, 3.0 * i as f64 / 49.0))
        .collect();
    let measured = response(&TRUTH, &freq_hz);
    // The stiffness may not exceed 20000 N/m: the fit ends on that bound.
    let upper = [1.0, 10.0, 20000.0];
    let lower = [0.01, 0.1, 1000.0];
    let mut model = |p: &[f64]| Ok(response(p, &freq_hz));
    let f = fit(
        &mut model,
        &measured,
        &[0.1, 1.0, 10000.0],
        &lower,
        &upper,
        100,
    )
    .unwrap();
    assert!(
        f.params[2] <= 20000.0 * (1.0 + 1e-6) && f.params[2] > 19000.0,
        "{:?}",
        f.params
    );
}
