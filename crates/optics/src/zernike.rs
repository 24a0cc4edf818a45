//! Zernike polynomial departures on a normalisation radius R (ρ = r/R), in the two orders
//! optical design programs use:
//! - **Standard** (Noll 1976; Zemax "Zernike Standard Sag"): term j is
//!   `N R_n^|m|(ρ) · {cos mθ (j even), sin mθ (j odd)}`, normalised to unit RMS over the
//!   pupil, `N = √(n+1)` for m = 0 and `√(2(n+1))` otherwise;
//! - **Fringe** (University of Arizona; Zemax "Zernike Fringe Sag", 37 terms): unnormalised,
//!   ordered by `(n + |m|)/2`, then by falling |m| with cos before sin, term 37 the
//!   12th-order spherical.
//!
//! θ is measured from +x toward +y. Coefficients are lengths (m).

use super::Sag;
use serde::{Deserialize, Serialize};

/// Fringe terms defined.
pub const FRINGE_TERMS: usize = 37;

/// The numbering of the coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ZernikeOrder {
    /// Noll's numbering, unit-RMS normalisation.
    Standard,
    /// Fringe numbering, unnormalised, 37 terms.
    Fringe,
}

/// Radial order n and signed azimuthal order m (m > 0: cos mθ, m < 0: sin |m|θ) of Noll term
/// `j` (1-based).
pub fn noll(j: usize) -> (u32, i32) {
    let (mut n, mut rest) = (0usize, j - 1);
    while rest > n {
        n += 1;
        rest -= n;
    }
    let m = (n % 2 + 2 * ((rest + (n + 1) % 2) / 2)) as i32;
    (n as u32, if j.is_multiple_of(2) { m } else { -m })
}

/// Radial order n and signed azimuthal order m of Fringe term `j` (1 ≤ j ≤ 37).
pub fn fringe(j: usize) -> (u32, i32) {
    if j == FRINGE_TERMS {
        return (12, 0);
    }
    let d = ((j - 1) as f64).sqrt().floor() as i32; // group: (n + |m|)/2
    let k = (j - 1) as i32 - d * d; // position in the group, 0 … 2d
    let m_abs = d - k / 2;
    let n = (2 * d - m_abs) as u32;
    let m = if m_abs == 0 || k % 2 == 0 {
        m_abs
    } else {
        -m_abs
    };
    (n, m)
}

/// Radial orders whose coefficients are tabled once per process.
const TABLED_ORDERS: u32 = 40;

/// The coefficients `(−1)^k (n−k)! / (k! ((n+m)/2−k)! ((n−m)/2−k)!)` of `ρ^(n−2k)` in
/// `R_n^m`, k = 0 … (n−m)/2, by their ratio.
fn coefficients(n: u32, m: u32) -> Vec<f64> {
    let (a, b) = ((n + m) / 2, (n - m) / 2);
    // k = 0: n! / (a! b!) = C(n, b).
    let mut c = (0..b).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1));
    let mut out = Vec::with_capacity(b as usize + 1);
    for k in 0..=b {
        out.push(c);
        if k < b {
            c *= -f64::from((a - k) * (b - k)) / f64::from((n - k) * (k + 1));
        }
    }
    out
}

/// [`coefficients`] for every n ≤ [`TABLED_ORDERS`], m ≤ n, built on first use.
fn tabled(n: u32, m: u32) -> Option<&'static [f64]> {
    static TABLE: std::sync::OnceLock<Vec<Vec<f64>>> = std::sync::OnceLock::new();
    let size = TABLED_ORDERS + 1;
    if n > TABLED_ORDERS {
        return None;
    }
    let table = TABLE.get_or_init(|| {
        (0..size * size)
            .map(|i| {
                let (n, m) = (i / size, i % size);
                if m <= n && (n - m) % 2 == 0 {
                    coefficients(n, m)
                } else {
                    Vec::new()
                }
            })
            .collect()
    });
    table.get((n * size + m) as usize).map(Vec::as_slice)
}

/// `R_n^m(ρ)`, `dR/dρ` and `R/ρ` (finite on the axis for m ≥ 1; unused for m = 0), from the
/// powers `ρ^k` of `p`.
fn radial(n: u32, m: u32, p: &Polar) -> (f64, f64, f64) {
    let owned;
    let cs = match tabled(n, m) {
        Some(cs) => cs,
        None => {
            owned = coefficients(n, m);
            &owned
        }
    };
    let (mut r, mut dr, mut r_over) = (0.0, 0.0, 0.0);
    for (k, &c) in cs.iter().enumerate() {
        let e = n - 2 * k as u32;
        r += c * p.rho_pow(e);
        if e > 0 {
            let below = p.rho_pow(e - 1);
            dr += c * f64::from(e) * below;
            r_over += c * below;
        }
    }
    (r, dr, r_over)
}

/// A Zernike departure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Zernike {
    /// Numbering and normalisation of the coefficients.
    pub order: ZernikeOrder,
    /// Normalisation radius R in m.
    pub norm_radius_m: f64,
    /// Coefficient of term j at index j − 1, m.
    pub coefficients_m: Vec<f64>,
}

impl Zernike {
    /// Orders (n, m) and normalisation of term `j`.
    fn term(&self, j: usize) -> (u32, i32, f64) {
        match self.order {
            ZernikeOrder::Standard => {
                let (n, m) = noll(j);
                let norm = if m == 0 { 1.0 } else { 2.0 };
                (n, m, (norm * f64::from(n + 1)).sqrt())
            }
            ZernikeOrder::Fringe => {
                let (n, m) = fringe(j);
                (n, m, 1.0)
            }
        }
    }

    /// The value of term `j` alone with unit coefficient, and its slopes, at `(x, y)` (m).
    pub fn basis(&self, j: usize, x: f64, y: f64) -> Sag {
        self.basis_at(j, &Polar::of(x, y, self.norm_radius_m))
    }

    /// [`Zernike::basis`] at a point already in polar form.
    fn basis_at(&self, j: usize, p: &Polar) -> Sag {
        let big_r = self.norm_radius_m;
        let rho = p.rho;
        let (n, m, norm) = self.term(j);
        let ma = m.unsigned_abs();
        let (radial, d_radial, radial_over_rho) = radial(n, ma, p);
        if ma == 0 {
            // z = N R(ρ): dz/dx = N R'(ρ) x/(rR); R'(ρ)/ρ is finite (R is even in ρ).
            let d_over_rho = if rho > 0.0 {
                d_radial / rho
            } else {
                2.0 * radial_second(n)
            };
            let g = norm * d_over_rho / (big_r * big_r);
            return Sag {
                z_m: norm * radial,
                dz_dx: g * p.x,
                dz_dy: g * p.y,
            };
        }
        let (cos_m, sin_m) = p.harmonic(ma);
        // Angular factor and its θ-derivative divided by |m|.
        let (a, da) = if m > 0 {
            (cos_m, -sin_m)
        } else {
            (sin_m, cos_m)
        };
        // dz/dρ = N R' a; (1/ρ) dz/dθ = N (R/ρ) |m| da.
        let dz_drho = norm * d_radial * a;
        let dz_dtheta_over_rho = norm * radial_over_rho * f64::from(ma) * da;
        let (c, s) = (p.cos[1], p.sin[1]);
        Sag {
            z_m: norm * radial * a,
            dz_dx: (dz_drho * c - dz_dtheta_over_rho * s) / big_r,
            dz_dy: (dz_drho * s + dz_dtheta_over_rho * c) / big_r,
        }
    }

    /// Sag and slopes at `(x, y)` (m).
    pub fn sag(&self, x: f64, y: f64) -> Sag {
        let p = Polar::of(x, y, self.norm_radius_m);
        self.coefficients_m
            .iter()
            .enumerate()
            .filter(|(_, c)| **c != 0.0)
            .fold(Sag::default(), |acc, (i, &c)| {
                let b = self.basis_at(i + 1, &p);
                acc + Sag {
                    z_m: c * b.z_m,
                    dz_dx: c * b.dz_dx,
                    dz_dy: c * b.dz_dy,
                }
            })
    }
}

/// Angular orders and powers of ρ a [`Polar`] holds (by recurrence, no trigonometry).
const HARMONICS: usize = 32;

/// A point in polar form on a normalisation radius: ρ and its first [`HARMONICS`] powers,
/// cos mθ and sin mθ for the first [`HARMONICS`] orders.
struct Polar {
    x: f64,
    y: f64,
    rho: f64,
    rho_pow: [f64; HARMONICS],
    cos: [f64; HARMONICS],
    sin: [f64; HARMONICS],
}

impl Polar {
    fn of(x: f64, y: f64, norm_radius_m: f64) -> Self {
        let r = libm::hypot(x, y);
        let rho = r / norm_radius_m;
        let mut rho_pow = [1.0; HARMONICS];
        for k in 1..HARMONICS {
            rho_pow[k] = rho_pow[k - 1] * rho;
        }
        // θ = atan2(y, x): 0 on the axis.
        let (c, s) = if r > 0.0 { (x / r, y / r) } else { (1.0, 0.0) };
        let (mut cos, mut sin) = ([1.0; HARMONICS], [0.0; HARMONICS]);
        for k in 1..HARMONICS {
            cos[k] = cos[k - 1] * c - sin[k - 1] * s;
            sin[k] = sin[k - 1] * c + cos[k - 1] * s;
        }
        Polar {
            x,
            y,
            rho,
            rho_pow,
            cos,
            sin,
        }
    }

    /// ρ^k.
    fn rho_pow(&self, k: u32) -> f64 {
        match self.rho_pow.get(k as usize) {
            Some(&v) => v,
            None => self.rho.powi(k as i32),
        }
    }

    /// (cos mθ, sin mθ).
    fn harmonic(&self, m: u32) -> (f64, f64) {
        match self.cos.get(m as usize) {
            Some(&c) => (c, self.sin[m as usize]),
            None => {
                let theta = f64::from(m) * libm::atan2(self.y, self.x);
                (libm::cos(theta), libm::sin(theta))
            }
        }
    }
}

/// The ρ² coefficient of `R_n^0` (k = n/2 − 1 in the sum; 0 for n = 0): half of `R'(ρ)/ρ`
/// on the axis.
fn radial_second(n: u32) -> f64 {
    if n < 2 {
        return 0.0;
    }
    let k = (n / 2 - 1) as usize;
    match tabled(n, 0) {
        Some(cs) => cs[k],
        None => coefficients(n, 0)[k],
    }
}
