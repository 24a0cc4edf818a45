//! The base surface: a conic of curvature `c` and conic constant `k` with even-asphere terms
//! (Zemax "Even Asphere"): `z = c r² / (1 + √(1 − (1 + k) c² r²)) + Σᵢ αᵢ r²ⁱ`, i = 1, 2, …

use super::Sag;
use serde::{Deserialize, Serialize};

/// A conic with even-asphere terms; lengths in m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Conic {
    /// Curvature c = 1/R in 1/m (0: a plane).
    pub curvature_per_m: f64,
    /// Conic constant k (0 sphere, −1 paraboloid, < −1 hyperboloid, > 0 oblate ellipsoid).
    pub conic: f64,
    /// αᵢ, the coefficient of r²ⁱ for i = 1, 2, … in m^(1−2i).
    pub even_asphere: Vec<f64>,
}

impl Conic {
    /// The radius where the conic's square root vanishes, m (∞ when it never does).
    pub fn limit_radius_m(&self) -> f64 {
        let q = (1.0 + self.conic) * self.curvature_per_m * self.curvature_per_m;
        if q > 0.0 {
            1.0 / q.sqrt()
        } else {
            f64::INFINITY
        }
    }

    /// Sag and slopes at `(x, y)` (m); NaN beyond [`Conic::limit_radius_m`].
    pub fn sag(&self, x: f64, y: f64) -> Sag {
        let r2 = x * x + y * y;
        let c = self.curvature_per_m;
        let root = (1.0 - (1.0 + self.conic) * c * c * r2).sqrt();
        let mut z = c * r2 / (1.0 + root);
        // dz/dr divided by r, so the slopes are finite on the axis.
        let mut dz_over_r = c / root;
        let mut power = 1.0; // r^(2i − 2)
        for (k, a) in self.even_asphere.iter().enumerate() {
            let i = (k + 1) as f64;
            dz_over_r += 2.0 * i * a * power;
            power *= r2;
            z += a * power;
        }
        Sag {
            z_m: z,
            dz_dx: dz_over_r * x,
            dz_dy: dz_over_r * y,
        }
    }
}
