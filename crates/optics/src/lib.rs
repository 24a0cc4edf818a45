//! # optics
//!
//! Optical surface prescriptions as an optical designer hands them over (Zemax / CODE V
//! conventions), evaluated with their slopes: a base conic with even-asphere terms
//! ([`conic`]), Zernike departures in Noll (Standard) or Fringe order ([`zernike`]), XY
//! polynomials ([`polynomial`]) and a measured sag grid ([`grid`]), summed, placed off axis,
//! less a previous cut's error map; the tool-nose compensation that turns them into a tool
//! path ([`nose`]) and its split between the Z slide and the FTS ([`toolpath`]).
//!
//! Conventions: sag `z(x, y)` in m along +z from the vertex plane (Zemax's sign: a positive
//! curvature bends the surface toward +z away from the vertex), `x, y` in m in the part's
//! frame on the spindle axis. Every term returns the sag and its two slopes `∂z/∂x, ∂z/∂y`.
//!
//! ```
//! use optics::{Conic, Prescription};
//! // A sphere of radius 100 mm: sag at r = 10 mm is R − √(R² − r²).
//! let p = Prescription::of_base(Conic { curvature_per_m: 10.0, conic: 0.0, even_asphere: vec![] });
//! let s = p.sag(0.01, 0.0);
//! assert!((s.z_m - (0.1 - (0.1f64 * 0.1 - 1e-4).sqrt())).abs() < 1e-16);
//! ```

pub mod conic;
pub mod grid;
pub mod nose;
pub mod polynomial;
pub mod toolpath;
pub mod zernike;

pub use conic::Conic;
pub use grid::SagGrid;
pub use polynomial::XyPolynomial;
pub use zernike::{Zernike, ZernikeOrder};

use serde::{Deserialize, Serialize};

/// Sag in m and its slopes (dimensionless) at one point.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Sag {
    /// Sag z in m.
    pub z_m: f64,
    /// ∂z/∂x.
    pub dz_dx: f64,
    /// ∂z/∂y.
    pub dz_dy: f64,
}

impl core::ops::Add for Sag {
    type Output = Sag;
    fn add(self, o: Sag) -> Sag {
        Sag {
            z_m: self.z_m + o.z_m,
            dz_dx: self.dz_dx + o.dz_dx,
            dz_dy: self.dz_dy + o.dz_dy,
        }
    }
}

/// A surface prescription: the sum of the terms present, evaluated in the part's frame.
/// With a decentre `(dx, dy)` the part is the off-axis segment of the parent surface centred
/// at `(dx, dy)`: `z_part(x, y) = z(x + dx, y + dy) − z(dx, dy)` (its centre at height 0).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Prescription {
    /// Base conic with even-asphere terms.
    pub base: Option<Conic>,
    /// Zernike departure.
    pub zernike: Option<Zernike>,
    /// XY polynomial departure.
    pub xy: Option<XyPolynomial>,
    /// Measured or designed sag grid departure (in the parent surface's frame).
    pub grid: Option<SagGrid>,
    /// The error map of a previous cut (sag of the part minus the design, in the part's frame,
    /// as an interferometer reports it), subtracted so the next cut compensates it.
    pub compensation: Option<SagGrid>,
    /// Position of the part's centre in the parent surface's frame, m.
    pub decenter_m: [f64; 2],
    /// Radius of the clear aperture on the part, m.
    pub aperture_radius_m: f64,
}

/// Largest radial order of a Zernike term (Noll 231 terms; higher orders lose digits to
/// cancellation in the radial polynomial).
pub const MAX_ZERNIKE_ORDER: u32 = 20;

/// Largest number of even-asphere terms (Zemax's Even Asphere has 8).
pub const MAX_ASPHERE_TERMS: usize = 16;

/// Largest number of XY terms, and their largest total degree.
pub const MAX_XY_TERMS: usize = 66;

/// Largest total degree of an XY term.
pub const MAX_XY_DEGREE: u32 = 20;

/// Largest sag grid, nodes.
pub const MAX_GRID_NODES: usize = 1 << 22;

impl Prescription {
    /// Checks what a prescription can hold, as a file or a recording's copy brings it: finite
    /// values, term counts and orders within the limits above, grids whose node count matches
    /// their size and that cover the aperture. The error names the part (`base.conic`,
    /// `grid.sag_m`, …) and what is allowed.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let bad = |key: &str, allowed: &str| Err((key.to_owned(), allowed.to_owned()));
        let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
        if !(self.aperture_radius_m > 0.0 && self.aperture_radius_m <= 0.5) {
            return bad("aperture_radius_m", "(0, 0.5] m");
        }
        if !finite(&self.decenter_m) || self.decenter_m.iter().any(|d| d.abs() > 1.0) {
            return bad("decenter_m", "finite, within ±1 m");
        }
        let reach = self.aperture_radius_m + libm::hypot(self.decenter_m[0], self.decenter_m[1]);
        if let Some(b) = &self.base {
            if !finite(&[b.curvature_per_m, b.conic]) || !finite(&b.even_asphere) {
                return bad("base", "finite curvature, conic and asphere terms");
            }
            if b.even_asphere.len() > MAX_ASPHERE_TERMS {
                return bad(
                    "base.even_asphere",
                    &format!("at most {MAX_ASPHERE_TERMS} terms"),
                );
            }
            if b.limit_radius_m() <= reach {
                return bad("base.conic", "a conic defined out to the aperture's edge");
            }
        }
        if let Some(z) = &self.zernike {
            let max = match z.order {
                ZernikeOrder::Standard => {
                    (MAX_ZERNIKE_ORDER as usize + 1) * (MAX_ZERNIKE_ORDER as usize + 2) / 2
                }
                ZernikeOrder::Fringe => zernike::FRINGE_TERMS,
            };
            if z.coefficients_m.len() > max {
                return bad(
                    "zernike.coefficients",
                    &format!("at most {max} terms in {:?} order", z.order),
                );
            }
            if !(finite(&z.coefficients_m) && z.norm_radius_m > 0.0 && z.norm_radius_m.is_finite())
            {
                return bad(
                    "zernike",
                    "finite coefficients and a positive normalisation radius",
                );
            }
        }
        if let Some(p) = &self.xy {
            if p.terms.len() > MAX_XY_TERMS {
                return bad("xy.terms", &format!("at most {MAX_XY_TERMS} terms"));
            }
            let degree_ok = |t: &polynomial::XyTerm| {
                t.x_power <= MAX_XY_DEGREE
                    && t.y_power <= MAX_XY_DEGREE
                    && t.x_power + t.y_power <= MAX_XY_DEGREE
            };
            if !p
                .terms
                .iter()
                .all(|t| degree_ok(t) && t.coefficient_m.is_finite())
            {
                return bad(
                    "xy.terms",
                    &format!("finite coefficients of total degree ≤ {MAX_XY_DEGREE}"),
                );
            }
            if !(p.norm_radius_m > 0.0 && p.norm_radius_m.is_finite()) {
                return bad("xy.norm_radius", "a positive normalisation radius");
            }
        }
        for (name, grid, centre) in [
            ("grid", &self.grid, self.decenter_m),
            ("compensation", &self.compensation, [0.0; 2]),
        ] {
            let Some(g) = grid else { continue };
            if g.columns < 4 || g.rows < 4 || g.columns.saturating_mul(g.rows) > MAX_GRID_NODES {
                return bad(name, &format!("4 × 4 to {MAX_GRID_NODES} nodes"));
            }
            if g.sag_m.len() != g.columns * g.rows || !finite(&g.sag_m) {
                return bad(name, "one finite sag per node");
            }
            if !g.pitch_m.iter().all(|p| *p > 0.0 && p.is_finite()) {
                return bad(name, "a positive pitch");
            }
            if !g.covers(centre, self.aperture_radius_m) {
                return bad(name, "a grid covering the aperture");
            }
        }
        Ok(())
    }

    /// A base conic alone, on axis, its aperture unbounded (the doc example's shape).
    pub fn of_base(base: Conic) -> Self {
        Prescription {
            base: Some(base),
            aperture_radius_m: f64::INFINITY,
            ..Prescription::default()
        }
    }

    /// Sag of the parent surface at `(x, y)` in its own frame, m.
    fn parent(&self, x: f64, y: f64) -> Sag {
        let mut s = Sag::default();
        if let Some(b) = &self.base {
            s = s + b.sag(x, y);
        }
        if let Some(z) = &self.zernike {
            s = s + z.sag(x, y);
        }
        if let Some(p) = &self.xy {
            s = s + p.sag(x, y);
        }
        if let Some(g) = &self.grid {
            s = s + g.sag(x, y);
        }
        s
    }

    /// Sag and slopes at `(x_m, y_m)` in the part's frame (see the type's decentre).
    pub fn sag(&self, x_m: f64, y_m: f64) -> Sag {
        let [dx, dy] = self.decenter_m;
        let mut s = self.parent(x_m + dx, y_m + dy);
        if dx != 0.0 || dy != 0.0 {
            s.z_m -= self.parent(dx, dy).z_m;
        }
        if let Some(c) = &self.compensation {
            let e = c.sag(x_m, y_m);
            s = Sag {
                z_m: s.z_m - e.z_m,
                dz_dx: s.dz_dx - e.dz_dx,
                dz_dy: s.dz_dy - e.dz_dy,
            };
        }
        s
    }
}
