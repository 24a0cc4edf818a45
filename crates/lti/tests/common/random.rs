//! Random Riccati problems (seeded): the same ones for the tests and for the comparison with
//! SciPy and SLICOT (`examples/riccati_export.rs`).

use nalgebra::DMatrix;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A Riccati problem's data.
pub struct Data {
    /// n × n.
    pub a: DMatrix<f64>,
    /// n × m.
    pub b: DMatrix<f64>,
    /// n × n, positive semi-definite.
    pub q: DMatrix<f64>,
    /// m × m, positive definite.
    pub r: DMatrix<f64>,
    /// The cross term, n × m.
    pub s: Option<DMatrix<f64>>,
}

/// A standard-normal matrix.
pub fn gaussian(rng: &mut Xoshiro256PlusPlus, r: usize, c: usize) -> DMatrix<f64> {
    DMatrix::from_fn(r, c, |_, _| StandardNormal.sample(rng))
}

/// A with unstable modes (spectral abscissa ≈ 1 continuous, radius ≈ 1.5 discrete), m = n/4
/// inputs, `Q = CᵀC` of rank n/2, `[Q S; Sᵀ R] ≥ 0` through `S = CᵀD`, `R = I + DᵀD`.
pub fn problem(n: usize, seed: u64, cross: bool, discrete: bool) -> Data {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let (m, p) = ((n / 4).max(1), (n / 2).max(1));
    let scale = if discrete { 1.5 } else { 1.0 };
    let a = gaussian(&mut rng, n, n) * (scale / (n as f64).sqrt());
    let b = gaussian(&mut rng, n, m);
    let c = gaussian(&mut rng, p, n);
    let d = gaussian(&mut rng, p, m) * 0.3;
    let r = DMatrix::identity(m, m) + d.transpose() * &d;
    let s = cross.then(|| c.transpose() * &d);
    Data {
        a,
        b,
        q: c.transpose() * c,
        r,
        s,
    }
}
