//! A surface error's form as an optician reports it, one convention for every report of
//! fts-servo (`servo toolpath`'s prediction, a registered measurement): PV and RMS after piston
//! and tilt (Standard Zernike terms 1–3 fitted and removed) and after power as well (1–4), and
//! the Standard (Noll, unit-RMS) Zernike coefficients on the aperture.

use nalgebra::{DMatrix, DVector};
use optics::{Zernike, ZernikeOrder};
use serde::Serialize;

/// Zernike terms fitted to a form error (Standard order).
pub const FITTED_TERMS: usize = 37;

/// PV and RMS of a surface error with some terms removed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Residual {
    /// Peak-to-valley, m.
    pub pv_m: f64,
    /// RMS, m.
    pub rms_m: f64,
}

/// A surface error's form.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Form {
    /// Piston and tilt removed (Noll 1–3).
    pub tilt_removed: Residual,
    /// Piston, tilt and power removed (Noll 1–4).
    pub power_removed: Residual,
    /// Standard (Noll, unit-RMS) Zernike coefficients on the aperture, m, term j at index j − 1.
    pub zernike_standard_m: Vec<f64>,
}

/// The form of the error `points` (`x, y` in m in the part's frame, error in m) on the
/// aperture of radius `aperture_m`.
pub fn form_of(points: &[(f64, f64, f64)], aperture_m: f64) -> Form {
    let basis = Zernike {
        order: ZernikeOrder::Standard,
        norm_radius_m: aperture_m,
        coefficients_m: Vec::new(),
    };
    let a = DMatrix::from_fn(points.len(), FITTED_TERMS, |i, j| {
        basis.basis(j + 1, points[i].0, points[i].1).z_m
    });
    let b = DVector::from_iterator(points.len(), points.iter().map(|p| p.2));
    let solve = |k: usize| {
        let sub = a.columns(0, k).into_owned();
        sub.clone()
            .svd(true, true)
            .solve(&b, 1e-12)
            .map(|c| (c.clone(), &b - sub * c))
            .unwrap_or_else(|_| (DVector::zeros(k), b.clone()))
    };
    let residual = |r: DVector<f64>| {
        let n = r.len().max(1) as f64;
        Residual {
            pv_m: if r.is_empty() { 0.0 } else { r.max() - r.min() },
            rms_m: (r.norm_squared() / n).sqrt(),
        }
    };
    let (all, _) = solve(FITTED_TERMS);
    Form {
        tilt_removed: residual(solve(3).1),
        power_removed: residual(solve(4).1),
        zernike_standard_m: all.iter().copied().collect(),
    }
}
