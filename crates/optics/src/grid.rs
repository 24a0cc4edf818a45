//! A sag grid (Zemax "Grid Sag": a measured error map or a designed departure): values on a
//! regular grid centred on its frame's origin (the parent surface's vertex for a departure, the
//! part's centre for a compensation), row 0 at +y and column 0 at −x as Zemax stores them,
//! interpolated by bicubic convolution (Keys 1981, a = −½, Catmull–Rom): it passes through
//! every node, its slope is continuous, and it reproduces quadratics exactly away from the
//! edges. Beyond the edge nodes the grid is extended linearly (ghost node `2z₀ − z₁`).

use super::Sag;
use serde::{Deserialize, Serialize};

/// A sag grid; lengths in m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SagGrid {
    /// Node spacing along x and y, m.
    pub pitch_m: [f64; 2],
    /// Nodes per row (along x).
    pub columns: usize,
    /// Rows (along y).
    pub rows: usize,
    /// Row-major sag values, m: `rows × columns`, row 0 at the largest y.
    pub sag_m: Vec<f64>,
}

/// Keys' cubic convolution weights for the four nodes around a fraction `t` ∈ [0, 1), and
/// their derivatives with respect to `t`.
pub(crate) fn weights(t: f64) -> ([f64; 4], [f64; 4]) {
    let (t2, t3) = (t * t, t * t * t);
    (
        [
            0.5 * (-t3 + 2.0 * t2 - t),
            0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
            0.5 * (-3.0 * t3 + 4.0 * t2 + t),
            0.5 * (t3 - t2),
        ],
        [
            0.5 * (-3.0 * t2 + 4.0 * t - 1.0),
            0.5 * (9.0 * t2 - 10.0 * t),
            0.5 * (-9.0 * t2 + 8.0 * t + 1.0),
            0.5 * (3.0 * t2 - 2.0 * t),
        ],
    )
}

impl SagGrid {
    /// Half the grid's extent along x and y, m (the outermost nodes).
    pub fn half_extent_m(&self) -> [f64; 2] {
        [
            0.5 * (self.columns - 1) as f64 * self.pitch_m[0],
            0.5 * (self.rows - 1) as f64 * self.pitch_m[1],
        ]
    }

    /// Whether the grid's nodes reach a circle of `radius_m` about `centre_m` (m), to a
    /// relative 1e-9 (a pitch written in decimal and read back).
    pub fn covers(&self, centre_m: [f64; 2], radius_m: f64) -> bool {
        let [hx, hy] = self.half_extent_m();
        let slack = 1.0 + 1e-9;
        (centre_m[0].abs() + radius_m) <= hx * slack && (centre_m[1].abs() + radius_m) <= hy * slack
    }

    /// Node value at integer column `i` and row-from-bottom `k`, extended linearly beyond
    /// the edges.
    fn node(&self, i: isize, k: isize) -> f64 {
        let (nc, nr) = (self.columns as isize, self.rows as isize);
        let at = |i: isize, k: isize| self.sag_m[((nr - 1 - k) * nc + i) as usize];
        let clamp = |v: isize, n: isize| v.clamp(0, n - 1);
        let (ic, kc) = (clamp(i, nc), clamp(k, nr));
        let base = at(ic, kc);
        // Linear extension: the slope of the edge cell times the distance beyond it.
        let di = i - ic;
        let dk = k - kc;
        let mut v = base;
        if di != 0 && nc > 1 {
            let inner = clamp(ic - di.signum(), nc);
            v += (base - at(inner, kc)) * di.abs() as f64;
        }
        if dk != 0 && nr > 1 {
            let inner = clamp(kc - dk.signum(), nr);
            v += (base - at(ic, inner)) * dk.abs() as f64;
        }
        v
    }

    /// Sag and slopes at `(x, y)` (m).
    pub fn sag(&self, x: f64, y: f64) -> Sag {
        let [hx, hy] = self.half_extent_m();
        let u = (x + hx) / self.pitch_m[0];
        let v = (y + hy) / self.pitch_m[1];
        let (i0, k0) = (u.floor(), v.floor());
        let (wu, dwu) = weights(u - i0);
        let (wv, dwv) = weights(v - k0);
        let (i0, k0) = (i0 as isize, k0 as isize);
        let mut s = Sag::default();
        for (b, (&wk, &dwk)) in wv.iter().zip(&dwv).enumerate() {
            for (a, (&wi, &dwi)) in wu.iter().zip(&dwu).enumerate() {
                let z = self.node(i0 - 1 + a as isize, k0 - 1 + b as isize);
                s.z_m += wi * wk * z;
                s.dz_dx += dwi * wk * z;
                s.dz_dy += wi * dwk * z;
            }
        }
        s.dz_dx /= self.pitch_m[0];
        s.dz_dy /= self.pitch_m[1];
        s
    }
}
