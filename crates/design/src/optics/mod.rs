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
//! use design::optics::{Conic, Prescription};
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

impl Prescription {
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
