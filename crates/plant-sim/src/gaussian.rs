//! Standard normal numbers that are the same bits on every processor.
//!
//! `rand_distr`'s `StandardNormal` evaluates `exp` and `ln` through the platform's C library,
//! and glibc picks FMA variants of them at run time, so one seed gave different noise on a
//! processor with FMA than on one without. This generator uses Marsaglia's polar method with
//! the `libm` crate's logarithm (pure Rust, no run-time choice) and IEEE square root.

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// Pairs of independent N(0, 1) numbers from a seeded xoshiro256++ stream (Marsaglia's polar
/// method: two uniforms in the unit disc, scaled by `√(−2 ln s / s)`).
#[derive(Debug, Clone)]
pub struct Gaussian {
    rng: Xoshiro256PlusPlus,
    spare: Option<f64>,
}

impl Gaussian {
    /// The stream of `seed`.
    pub fn new(seed: u64) -> Self {
        Gaussian {
            rng: Xoshiro256PlusPlus::seed_from_u64(seed),
            spare: None,
        }
    }

    /// The next N(0, 1) number.
    #[inline]
    pub fn sample(&mut self) -> f64 {
        if let Some(x) = self.spare.take() {
            return x;
        }
        loop {
            let u = 2.0 * self.rng.random::<f64>() - 1.0;
            let v = 2.0 * self.rng.random::<f64>() - 1.0;
            let s = u * u + v * v;
            if s > 0.0 && s < 1.0 {
                let k = (-2.0 * libm::log(s) / s).sqrt();
                self.spare = Some(v * k);
                return u * k;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Moments of 10⁶ samples against N(0, 1): mean 0 ± 5σ/√n, variance 1 ± 5·√(2/n),
    /// kurtosis 3 ± 5·√(24/n), and the share beyond 3σ against 2·(1 − Φ(3)) = 0.0026998.
    #[test]
    fn moments_and_tail_are_the_standard_normals() {
        let mut g = Gaussian::new(7);
        let n = 1_000_000;
        let (mut m1, mut m2, mut m4, mut beyond3) = (0.0, 0.0, 0.0, 0u32);
        for _ in 0..n {
            let x = g.sample();
            m1 += x;
            m2 += x * x;
            m4 += x * x * x * x;
            beyond3 += u32::from(x.abs() > 3.0);
        }
        let nf = n as f64;
        let (mean, var, kurt) = (m1 / nf, m2 / nf, m4 / nf);
        assert!(mean.abs() < 5.0 / nf.sqrt(), "mean {mean}");
        assert!(
            (var - 1.0).abs() < 5.0 * (2.0 / nf).sqrt(),
            "variance {var}"
        );
        assert!(
            (kurt - 3.0).abs() < 5.0 * (24.0 / nf).sqrt(),
            "kurtosis {kurt}"
        );
        let p = f64::from(beyond3) / nf;
        let want = 0.002_699_796;
        assert!((p - want).abs() < 5.0 * (want / nf).sqrt(), "beyond 3σ {p}");
    }

    #[test]
    fn a_seed_is_one_stream() {
        let (mut a, mut b) = (Gaussian::new(3), Gaussian::new(3));
        assert!((0..1001).all(|_| a.sample().to_bits() == b.sample().to_bits()));
    }
}
