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

/// `R_n^m(ρ)`, `dR/dρ` and `R/ρ` (finite on the axis for m ≥ 1; unused for m = 0).
/// The coefficients `(−1)^k (n−k)! / (k! ((n+m)/2−k)! ((n−m)/2−k)!)` by their ratio.
fn radial(n: u32, m: u32, rho: f64) -> (f64, f64, f64) {
    let (a, b) = ((n + m) / 2, (n - m) / 2);
    // k = 0: n! / (a! b!) = C(n, b).
    let mut c = (0..b).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1));
    let (mut r, mut dr, mut r_over) = (0.0, 0.0, 0.0);
    for k in 0..=b {
        let p = (n - 2 * k) as i32;
        r += c * rho.powi(p);
        if p > 0 {
            dr += c * f64::from(p) * rho.powi(p - 1);
            r_over += c * rho.powi(p - 1);
        }
        if k < b {
            c *= -f64::from((a - k) * (b - k)) / f64::from((n - k) * (k + 1));
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
        let big_r = self.norm_radius_m;
        let r = libm::hypot(x, y);
        let rho = r / big_r;
        let (n, m, norm) = self.term(j);
        let ma = m.unsigned_abs();
        let (radial, d_radial, radial_over_rho) = radial(n, ma, rho);
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
                dz_dx: g * x,
                dz_dy: g * y,
            };
        }
        let (c, s) = if r > 0.0 { (x / r, y / r) } else { (1.0, 0.0) };
        let theta = libm::atan2(y, x);
        let (cos_m, sin_m) = (
            libm::cos(f64::from(ma) * theta),
            libm::sin(f64::from(ma) * theta),
        );
        // Angular factor and its θ-derivative divided by |m|.
        let (a, da) = if m > 0 {
            (cos_m, -sin_m)
        } else {
            (sin_m, cos_m)
        };
        // dz/dρ = N R' a; (1/ρ) dz/dθ = N (R/ρ) |m| da.
        let dz_drho = norm * d_radial * a;
        let dz_dtheta_over_rho = norm * radial_over_rho * f64::from(ma) * da;
        Sag {
            z_m: norm * radial * a,
            dz_dx: (dz_drho * c - dz_dtheta_over_rho * s) / big_r,
            dz_dy: (dz_drho * s + dz_dtheta_over_rho * c) / big_r,
        }
    }

    /// Sag and slopes at `(x, y)` (m).
    pub fn sag(&self, x: f64, y: f64) -> Sag {
        self.coefficients_m
            .iter()
            .enumerate()
            .filter(|(_, c)| **c != 0.0)
            .fold(Sag::default(), |acc, (i, &c)| {
                let b = self.basis(i + 1, x, y);
                acc + Sag {
                    z_m: c * b.z_m,
                    dz_dx: c * b.dz_dx,
                    dz_dy: c * b.dz_dy,
                }
            })
    }
}

/// The ρ² coefficient of `R_n^0` (k = n/2 − 1 in the sum; 0 for n = 0): half of `R'(ρ)/ρ`
/// on the axis.
fn radial_second(n: u32) -> f64 {
    if n < 2 {
        return 0.0;
    }
    let half = n / 2;
    let mut c = (0..half).fold(1.0, |acc, i| acc * f64::from(n - i) / f64::from(i + 1));
    for k in 0..half - 1 {
        c *= -f64::from((half - k) * (half - k)) / f64::from((n - k) * (k + 1));
    }
    c
}
