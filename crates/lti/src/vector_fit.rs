//! A stable rational fit of a sampled system's measured frequency response by vector fitting
//! in the z-domain (Gustavsen & Semlyen 1999, relaxed as Gustavsen 2006; the discrete form of
//! Wong & Lei 2004): `H(z) = d + Σ rᵢ/(z − aᵢ)`, poles relocated from a start spread over the
//! band by repeated linear least squares on `σ(z)·H(z) ≈ p(z)`, each bin weighted (by the
//! inverse of its uncertainty, typically), unstable poles reflected into the unit circle
//! (`a → 1/ā`) at every step. In the z-domain a servo's delays and zero-order hold are exact
//! (a one-tick delay is one pole at 0), which a fit in `s` would need many poles to mimic.
//!
//! Real systems only: poles are real or in conjugate pairs, and the basis is the real one
//! (`1/(z − a) + 1/(z − ā)`, `j/(z − a) − j/(z − ā)`) so the fitted model is real by
//! construction.

use crate::state_space::{eigenvalues, LtiError, StateSpace};
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Largest order [`vector_fit`] takes.
pub const MAX_ORDER: usize = 60;

/// A fitted rational model of a sampled system: `H(z) = direct + Σ residues[i]/(z − poles[i])`,
/// `z = exp(j·2π·f·period_s)`.
#[derive(Debug, Clone, PartialEq)]
pub struct RationalFit {
    /// Poles in z, each inside the unit circle; a complex pole is followed by its conjugate.
    pub poles: Vec<Complex64>,
    /// The residue of each pole (conjugate for conjugate poles).
    pub residues: Vec<Complex64>,
    /// The direct term (the response's value at z → ∞).
    pub direct: f64,
    /// The sample period, s.
    pub period_s: f64,
}

/// A pole of the fit as a continuous-time mode: `s = ln(a)/T`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency `|s|/2π`, Hz.
    pub hz: f64,
    /// Damping ratio `−Re s/|s|` (1 for a real pole, 0 on the unit circle).
    pub zeta: f64,
}

impl RationalFit {
    /// The model at `f_hz`.
    pub fn response(&self, f_hz: f64) -> Complex64 {
        let z = unit(f_hz * self.period_s);
        self.poles
            .iter()
            .zip(&self.residues)
            .map(|(a, r)| r / (z - a))
            .sum::<Complex64>()
            + self.direct
    }

    /// The number of poles.
    pub fn order(&self) -> usize {
        self.poles.len()
    }

    /// The modes of the fit, one per real pole or conjugate pair, in the order of the poles.
    pub fn modes(&self) -> Vec<Mode> {
        real_blocks(&self.poles)
            .iter()
            .map(|&(i, _)| {
                let a = self.poles[i];
                if a.norm() == 0.0 {
                    // A pure delay: infinitely fast, fully damped.
                    return Mode {
                        hz: f64::INFINITY,
                        zeta: 1.0,
                    };
                }
                let s =
                    Complex64::new(libm::log(a.norm()), libm::atan2(a.im, a.re)) / self.period_s;
                let w = s.norm();
                Mode {
                    hz: w / (2.0 * std::f64::consts::PI),
                    zeta: if w > 0.0 { -s.re / w } else { 1.0 },
                }
            })
            .collect()
    }

    /// The fit as a real discrete state space (one input, one output; the real form of the
    /// partial fractions).
    pub fn state_space(&self) -> StateSpace {
        let n = self.poles.len();
        let (mut a, mut b, mut c) = (
            DMatrix::zeros(n, n),
            DMatrix::zeros(n, 1),
            DMatrix::zeros(1, n),
        );
        for (i, pair) in real_blocks(&self.poles) {
            let (p, r) = (self.poles[i], self.residues[i]);
            if pair {
                a[(i, i)] = p.re;
                a[(i, i + 1)] = p.im;
                a[(i + 1, i)] = -p.im;
                a[(i + 1, i + 1)] = p.re;
                b[(i, 0)] = 2.0;
                c[(0, i)] = r.re;
                c[(0, i + 1)] = r.im;
            } else {
                a[(i, i)] = p.re;
                b[(i, 0)] = 1.0;
                c[(0, i)] = r.re;
            }
        }
        StateSpace {
            a,
            b,
            c,
            d: DMatrix::from_element(1, 1, self.direct),
        }
    }
}

/// `exp(j·2π·x)`.
fn unit(x: f64) -> Complex64 {
    let t = 2.0 * std::f64::consts::PI * x;
    Complex64::new(libm::cos(t), libm::sin(t))
}

/// The real blocks of `poles`: `(index, is a conjugate pair)` for each real pole and each pair
/// (a complex pole followed by its conjugate).
fn real_blocks(poles: &[Complex64]) -> Vec<(usize, bool)> {
    let mut blocks = Vec::new();
    let mut i = 0;
    while i < poles.len() {
        let pair = poles[i].im != 0.0;
        blocks.push((i, pair));
        i += if pair { 2 } else { 1 };
    }
    blocks
}

/// The real basis at `z`: one column per pole (`1/(z − a)` for a real pole;
/// `1/(z − a) + 1/(z − ā)` and `j/(z − a) − j/(z − ā)` for a pair).
fn basis(poles: &[Complex64], z: Complex64) -> Vec<Complex64> {
    let mut row = vec![Complex64::new(0.0, 0.0); poles.len()];
    for (i, pair) in real_blocks(poles) {
        let a = poles[i];
        if pair {
            let (p, q) = (1.0 / (z - a), 1.0 / (z - a.conj()));
            row[i] = p + q;
            row[i + 1] = Complex64::new(0.0, 1.0) * (p - q);
        } else {
            row[i] = 1.0 / (z - a);
        }
    }
    row
}

/// Least squares `min ‖M·x − y‖` with the columns scaled to unit norm first (the basis of
/// lightly damped poles spans decades).
fn least_squares(m: DMatrix<f64>, y: DVector<f64>) -> Result<DVector<f64>, LtiError> {
    let scale: Vec<f64> = m
        .column_iter()
        .map(|c| {
            let n = c.norm();
            if n > 0.0 {
                1.0 / n
            } else {
                1.0
            }
        })
        .collect();
    let mut scaled = m;
    for (j, s) in scale.iter().enumerate() {
        scaled.column_mut(j).scale_mut(*s);
    }
    let x = scaled
        .svd(true, true)
        .solve(&y, 1e-14)
        .map_err(|_| LtiError::Argument("vector fit: the least-squares problem has no solution"))?;
    Ok(DVector::from_iterator(
        x.len(),
        x.iter().zip(&scale).map(|(x, s)| x * s),
    ))
}

/// Conjugate pairs adjacent, real poles alone; a pole within `1e-12` of the real axis made
/// real. Order: by angle, then by radius.
fn canonical(mut poles: Vec<Complex64>) -> Vec<Complex64> {
    for p in &mut poles {
        if p.im.abs() <= 1e-12 * p.norm().max(1e-300) {
            p.im = 0.0;
        }
        // Stable: reflect into the unit circle.
        if p.norm() > 1.0 {
            *p = 1.0 / p.conj();
        }
    }
    let mut upper: Vec<Complex64> = poles.iter().copied().filter(|p| p.im >= 0.0).collect();
    upper.sort_by(|a, b| {
        libm::atan2(a.im, a.re)
            .total_cmp(&libm::atan2(b.im, b.re))
            .then(a.norm().total_cmp(&b.norm()))
    });
    let mut out = Vec::with_capacity(poles.len());
    for p in upper {
        out.push(p);
        if p.im > 0.0 {
            out.push(p.conj());
        }
    }
    out
}

/// Starting poles: `order/2` lightly damped pairs (ζ = 0.01) at frequencies spread
/// logarithmically over `[f_lo, f_hi]`, and one real pole for an odd order.
fn start_poles(order: usize, f_lo: f64, f_hi: f64, period_s: f64) -> Vec<Complex64> {
    let pairs = order / 2;
    let mut poles = Vec::with_capacity(order);
    for k in 0..pairs {
        let f = if pairs == 1 {
            libm::sqrt(f_lo * f_hi)
        } else {
            f_lo * libm::pow(f_hi / f_lo, k as f64 / (pairs - 1) as f64)
        };
        let w = 2.0 * std::f64::consts::PI * f;
        let s = Complex64::new(-0.01 * w, w);
        let r = libm::exp(s.re * period_s);
        let a = Complex64::new(
            r * libm::cos(s.im * period_s),
            r * libm::sin(s.im * period_s),
        );
        poles.push(a);
        poles.push(a.conj());
    }
    if order % 2 == 1 {
        poles.push(Complex64::new(
            libm::exp(-2.0 * std::f64::consts::PI * f_lo * period_s),
            0.0,
        ));
    }
    poles
}

/// Fits `H(z) = d + Σ rᵢ/(z − aᵢ)` of `order` poles to `h` at `freq_hz` (strictly increasing,
/// below the Nyquist frequency of `period_s`), minimising `Σ (weight·|H − h|)²`, in `iterations`
/// pole relocations (10–30 is typical; it stops early when the poles settle).
pub fn vector_fit(
    freq_hz: &[f64],
    h: &[Complex64],
    weight: &[f64],
    period_s: f64,
    order: usize,
    iterations: usize,
) -> Result<RationalFit, LtiError> {
    let n_bins = freq_hz.len();
    if h.len() != n_bins || weight.len() != n_bins {
        return Err(LtiError::Argument(
            "vector fit: frequencies, responses and weights differ in length",
        ));
    }
    if !(1..=MAX_ORDER).contains(&order) || n_bins < order + 1 {
        return Err(LtiError::Argument(
            "vector fit: the order must be 1–60 and the bins at least order + 1",
        ));
    }
    let finite = freq_hz
        .iter()
        .chain(weight)
        .all(|x| x.is_finite() && *x >= 0.0)
        && h.iter().all(|x| x.re.is_finite() && x.im.is_finite());
    if !finite
        || period_s.is_nan()
        || period_s <= 0.0
        || freq_hz.iter().any(|f| f * period_s >= 0.5)
    {
        return Err(LtiError::Argument(
            "vector fit: frequencies, responses and weights must be finite, below Nyquist",
        ));
    }
    let z: Vec<Complex64> = freq_hz.iter().map(|f| unit(f * period_s)).collect();
    let lo = freq_hz[0].max(1e-3 / period_s);
    let hi = freq_hz[n_bins - 1].max(lo * 1.01);
    let mut poles = start_poles(order, lo, hi, period_s);
    for _ in 0..iterations {
        let next = relocate(&poles, &z, h, weight)?;
        let moved = poles
            .iter()
            .zip(&next)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        poles = next;
        if moved < 1e-12 {
            break;
        }
    }
    let (residues, direct) = residues(&poles, &z, h, weight)?;
    Ok(RationalFit {
        poles,
        residues,
        direct,
        period_s,
    })
}

/// One relaxed pole relocation: the zeros of `σ(z) = d̃ + Σ c̃ᵢ·basisᵢ(z)` fitted with
/// `p(z) ≈ σ(z)·h(z)`, made stable.
fn relocate(
    poles: &[Complex64],
    z: &[Complex64],
    h: &[Complex64],
    weight: &[f64],
) -> Result<Vec<Complex64>, LtiError> {
    let (n, bins) = (poles.len(), z.len());
    let cols = 2 * n + 2;
    let mut m = DMatrix::zeros(2 * bins + 1, cols);
    let mut y = DVector::zeros(2 * bins + 1);
    let mut sigma_sum = vec![0.0; n + 1];
    for k in 0..bins {
        let phi = basis(poles, z[k]);
        let w = weight[k];
        let mut row = vec![Complex64::new(0.0, 0.0); cols];
        for i in 0..n {
            row[i] = w * phi[i];
            row[n + 1 + i] = -w * h[k] * phi[i];
            sigma_sum[i] += phi[i].re;
        }
        row[n] = Complex64::new(w, 0.0);
        row[2 * n + 1] = -w * h[k];
        sigma_sum[n] += 1.0;
        for (j, v) in row.iter().enumerate() {
            m[(2 * k, j)] = v.re;
            m[(2 * k + 1, j)] = v.im;
        }
    }
    // Relaxation: Re Σₖ σ(zₖ) = bins, weighted like the data.
    let scale = (0..bins)
        .map(|k| (weight[k] * h[k].norm()).powi(2))
        .sum::<f64>()
        .sqrt()
        / bins as f64;
    for (i, s) in sigma_sum.iter().enumerate() {
        m[(2 * bins, n + 1 + i)] = scale * s;
    }
    y[2 * bins] = scale * bins as f64;
    let x = least_squares(m, y)?;
    let c_sigma: Vec<f64> = x.rows(n + 1, n).iter().copied().collect();
    let d_sigma = x[2 * n + 1];
    if d_sigma.is_nan() || d_sigma.abs() <= 1e-8 {
        return Err(LtiError::Argument(
            "vector fit: the relaxed weight function vanished (try another order)",
        ));
    }
    let ss = RationalFit {
        poles: poles.to_vec(),
        residues: vec![Complex64::new(0.0, 0.0); n],
        direct: 0.0,
        period_s: 1.0,
    }
    .state_space();
    let c = DMatrix::from_row_slice(1, n, &c_sigma);
    let zeros = eigenvalues(&(&ss.a - &ss.b * &c / d_sigma));
    Ok(canonical(zeros))
}

/// Residues and direct term of fixed `poles` by weighted least squares.
fn residues(
    poles: &[Complex64],
    z: &[Complex64],
    h: &[Complex64],
    weight: &[f64],
) -> Result<(Vec<Complex64>, f64), LtiError> {
    let (n, bins) = (poles.len(), z.len());
    let mut m = DMatrix::zeros(2 * bins, n + 1);
    let mut y = DVector::zeros(2 * bins);
    for k in 0..bins {
        let phi = basis(poles, z[k]);
        let w = weight[k];
        for i in 0..n {
            m[(2 * k, i)] = w * phi[i].re;
            m[(2 * k + 1, i)] = w * phi[i].im;
        }
        m[(2 * k, n)] = w;
        y[2 * k] = w * h[k].re;
        y[2 * k + 1] = w * h[k].im;
    }
    let x = least_squares(m, y)?;
    let mut r = vec![Complex64::new(0.0, 0.0); n];
    for (i, pair) in real_blocks(poles) {
        if pair {
            r[i] = Complex64::new(x[i], x[i + 1]);
            r[i + 1] = r[i].conj();
        } else {
            r[i] = Complex64::new(x[i], 0.0);
        }
    }
    Ok((r, x[n]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A known sampled system: two lightly damped pairs, a real pole and a one-tick delay
    /// (a pole at 0), its response on 200 bins: the fit of the right order recovers the poles.
    #[test]
    fn the_poles_of_a_known_system_are_recovered() {
        let period = 1.0 / 20_000.0;
        let pole = |hz: f64, zeta: f64| {
            let w = 2.0 * std::f64::consts::PI * hz;
            let s = Complex64::new(-zeta * w, w * libm::sqrt(1.0 - zeta * zeta));
            let r = libm::exp(s.re * period);
            Complex64::new(r * libm::cos(s.im * period), r * libm::sin(s.im * period))
        };
        let (a1, a2) = (pole(180.0, 0.02), pole(2_400.0, 0.005));
        let truth = RationalFit {
            poles: vec![
                a1,
                a1.conj(),
                a2,
                a2.conj(),
                Complex64::new(0.9, 0.0),
                Complex64::new(0.0, 0.0),
            ],
            residues: vec![
                Complex64::new(0.3, -0.1),
                Complex64::new(0.3, 0.1),
                Complex64::new(-0.02, 0.05),
                Complex64::new(-0.02, -0.05),
                Complex64::new(0.05, 0.0),
                Complex64::new(0.2, 0.0),
            ],
            direct: 0.0,
            period_s: period,
        };
        let f = crate::spectral::log_space(10.0, 9_000.0, 200);
        let h: Vec<Complex64> = f.iter().map(|&f| truth.response(f)).collect();
        let w: Vec<f64> = h.iter().map(|h| 1.0 / h.norm()).collect();
        let fit = vector_fit(&f, &h, &w, period, 6, 30).unwrap();
        for p in &truth.poles {
            let nearest = fit
                .poles
                .iter()
                .map(|q| (q - p).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 1e-8, "{p}: {:?}", fit.poles);
        }
        for (&f, h) in f.iter().zip(&h) {
            assert!((fit.response(f) - h).norm() < 1e-8 * h.norm(), "{f} Hz");
        }
        // The continuous modes: the pairs' frequencies and damping.
        let modes = fit.modes();
        let near = |hz: f64, zeta: f64| {
            modes
                .iter()
                .any(|m| (m.hz / hz - 1.0).abs() < 1e-6 && (m.zeta / zeta - 1.0).abs() < 1e-6)
        };
        assert!(near(180.0, 0.02) && near(2_400.0, 0.005), "{modes:?}");
        // The state space is the same system.
        let ss = fit.state_space();
        for &fq in &[50.0, 180.0, 2_400.0, 8_000.0] {
            let g = crate::FrequencyResponse::new(&ss)
                .discrete(fq, period)
                .unwrap()[(0, 0)];
            assert!((g - truth.response(fq)).norm() < 1e-8 * g.norm(), "{fq} Hz");
        }
    }

    /// A start with unstable poles or data from an unstable system still ends inside the unit
    /// circle.
    #[test]
    fn every_fitted_pole_is_stable() {
        let period = 1e-4;
        let unstable = RationalFit {
            poles: vec![Complex64::new(1.05, 0.2), Complex64::new(1.05, -0.2)],
            residues: vec![Complex64::new(0.1, 0.1), Complex64::new(0.1, -0.1)],
            direct: 0.0,
            period_s: period,
        };
        let f = crate::spectral::log_space(10.0, 4_000.0, 100);
        let h: Vec<Complex64> = f.iter().map(|&f| unstable.response(f)).collect();
        let fit = vector_fit(&f, &h, &vec![1.0; f.len()], period, 4, 20).unwrap();
        assert!(fit.poles.iter().all(|p| p.norm() < 1.0), "{:?}", fit.poles);
    }
}
