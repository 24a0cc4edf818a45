//! XY polynomial departure (Zemax "Extended Polynomial" without its base):
//! `z = Σ C_ij (x/R)^i (y/R)^j` on a normalisation radius R.

use super::Sag;
use serde::{Deserialize, Serialize};

/// One term `C (x/R)^i (y/R)^j`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct XyTerm {
    /// Power of x/R.
    pub x_power: u32,
    /// Power of y/R.
    pub y_power: u32,
    /// Coefficient C in m.
    pub coefficient_m: f64,
}

/// An XY polynomial on a normalisation radius.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct XyPolynomial {
    /// Normalisation radius R in m.
    pub norm_radius_m: f64,
    /// The terms.
    pub terms: Vec<XyTerm>,
}

impl XyPolynomial {
    /// Sag and slopes at `(x, y)` (m).
    pub fn sag(&self, x: f64, y: f64) -> Sag {
        let r = self.norm_radius_m;
        let (u, v) = (x / r, y / r);
        let mut s = Sag::default();
        for t in &self.terms {
            let (i, j) = (t.x_power as i32, t.y_power as i32);
            let (ui, vj) = (u.powi(i), v.powi(j));
            s.z_m += t.coefficient_m * ui * vj;
            if i > 0 {
                s.dz_dx += t.coefficient_m * f64::from(i) * u.powi(i - 1) * vj / r;
            }
            if j > 0 {
                s.dz_dy += t.coefficient_m * f64::from(j) * ui * v.powi(j - 1) / r;
            }
        }
        s
    }
}
