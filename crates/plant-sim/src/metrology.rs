//! Simulated spindle metrology (thesis §8.4.1, Appendix D): a rotating artefact with a form
//! error, a spindle with synchronous radial error motion, and displacement probes around it
//! with asynchronous motion and probe noise. What each probe reads is eq D-1..D-3:
//! `S(θ) = A(θ − φ) + X(θ)·cos φ + Y(θ)·sin φ` for a probe at angle φ, plus noise.

use crate::gaussian::Gaussian;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::f64::consts::TAU;

/// A periodic profile over one revolution: `Σ_k a_k cos(kθ + φ_k)` (m).
#[derive(Debug, Clone, PartialEq)]
pub struct Harmonics {
    /// Amplitude of harmonic k (index k, UPR) in m.
    pub amplitude_m: Vec<f64>,
    /// Phase of harmonic k in rad.
    pub phase_rad: Vec<f64>,
}

impl Harmonics {
    /// Random phases and amplitudes falling as `1/k` from 2 UPR to `max_k`, scaled to an RMS
    /// of `rms_m` (0 and 1 UPR empty: offset and centring are set-up, not form).
    pub fn random(seed: u64, max_k: usize, rms_m: f64) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut amplitude_m: Vec<f64> = (0..=max_k)
            .map(|k| {
                if k < 2 {
                    0.0
                } else {
                    rng.random_range(0.5..1.5) / k as f64
                }
            })
            .collect();
        let phase_rad = (0..=max_k).map(|_| rng.random_range(0.0..TAU)).collect();
        let rms = (amplitude_m.iter().map(|a| a * a / 2.0).sum::<f64>()).sqrt();
        amplitude_m
            .iter_mut()
            .for_each(|a| *a *= rms_m / rms.max(1e-300));
        Harmonics {
            amplitude_m,
            phase_rad,
        }
    }

    /// The profile at angle `theta_rad`.
    pub fn at(&self, theta_rad: f64) -> f64 {
        self.amplitude_m
            .iter()
            .zip(&self.phase_rad)
            .enumerate()
            .map(|(k, (a, p))| a * libm::cos(k as f64 * theta_rad + p))
            .sum()
    }
}

/// The artefact, the spindle and the probes.
#[derive(Debug, Clone)]
pub struct ProbeRig {
    /// Artefact form error A(θ).
    pub artefact: Harmonics,
    /// Synchronous radial error motion along X.
    pub x: Harmonics,
    /// Synchronous radial error motion along Y.
    pub y: Harmonics,
    /// RMS of the asynchronous motion along X and Y, white per sample, in m.
    pub asynchronous_rms_m: f64,
    /// RMS of each probe's noise, white per sample, in m (Appendix D.3: 0.3 nm).
    pub probe_noise_rms_m: f64,
    /// Samples per revolution (Appendix D.3: 10 000).
    pub per_rev: usize,
}

impl ProbeRig {
    /// `revolutions` of the three probes at 0, `alpha_rad` and `beta_rad`, sample by sample
    /// (noise from `seed`).
    pub fn measure(
        &self,
        alpha_rad: f64,
        beta_rad: f64,
        revolutions: usize,
        seed: u64,
    ) -> [Vec<f64>; 3] {
        let mut gaussian = Gaussian::new(seed);
        let mut normal = move || gaussian.sample();
        let n = self.per_rev * revolutions;
        let mut out = [
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        ];
        // The synchronous profiles repeat: evaluate them once per angle.
        let one_rev: Vec<[f64; 5]> = (0..self.per_rev)
            .map(|i| {
                let th = i as f64 * TAU / self.per_rev as f64;
                [
                    self.artefact.at(th),
                    self.artefact.at(th - alpha_rad),
                    self.artefact.at(th - beta_rad),
                    self.x.at(th),
                    self.y.at(th),
                ]
            })
            .collect();
        for i in 0..n {
            let [a0, aa, ab, x, y] = one_rev[i % self.per_rev];
            let x = x + self.asynchronous_rms_m * normal();
            let y = y + self.asynchronous_rms_m * normal();
            let noise = self.probe_noise_rms_m;
            out[0].push(a0 + x + noise * normal());
            out[1]
                .push(aa + x * libm::cos(alpha_rad) + y * libm::sin(alpha_rad) + noise * normal());
            out[2].push(ab + x * libm::cos(beta_rad) + y * libm::sin(beta_rad) + noise * normal());
        }
        out
    }
}
