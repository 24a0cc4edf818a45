//! Freeform surfaces evaluated per servo tick from the spindle position (thesis §8.3, §8.5):
//! the depth of cut `z` (m) at X-axis radius `r` (m) and spindle angle `θ` (rad), computed in
//! the tick with no allocation, as the thesis's DSP did.
//!
//! ```
//! use servo_core::surface::{Surface, SinusoidalGrid};
//! let grid = SinusoidalGrid { ax_m: 5e-6, ay_m: 5e-6, lambda_x_m: 1e-3, lambda_y_m: 1e-3 };
//! let z = grid.depth_m(0.25e-3, 0.0); // x = 0.25 mm, y = 0: a crest along X
//! assert!((z - 5e-6).abs() < 1e-15);
//! ```

use core::f64::consts::TAU;

/// A surface the tool follows: depth of cut in m at polar position (`r_m`, `theta_rad`).
pub trait Surface {
    /// Depth in m at radius `r_m` (m) and spindle angle `theta_rad` (rad).
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64;

    /// The highest point of the surface in m: the face of the blank it is cut from (the depth
    /// of cut at a point is `peak_m − depth_m`).
    fn peak_m(&self) -> f64;
}

/// Cartesian position of the tool on the part: `x = r cos θ`, `y = r sin θ` (§8.5.3).
#[inline]
fn cartesian(r_m: f64, theta_rad: f64) -> (f64, f64) {
    (r_m * libm::cos(theta_rad), r_m * libm::sin(theta_rad))
}

/// Beam-integrator lenslet array (§8.5.3, Table 8-4): square cells of pitch `L`, each a
/// concave sphere of radius `R` centred in the cell:
/// `x_l = x − ⌊x/L⌋L − L/2`, `z = R − √(R² − x_l² − y_l²)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamIntegrator {
    /// Sphere radius R in m (thesis: 0.1).
    pub radius_m: f64,
    /// Cell pitch L in m (thesis: 2e-3).
    pub pitch_m: f64,
}

impl Surface for BeamIntegrator {
    #[inline]
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        let (x, y) = cartesian(r_m, theta_rad);
        let l = self.pitch_m;
        let local = |v: f64| v - libm::floor(v / l) * l - l / 2.0;
        let (xl, yl) = (local(x), local(y));
        self.radius_m - libm::sqrt(self.radius_m * self.radius_m - (xl * xl + yl * yl))
    }

    /// At the cell corners.
    fn peak_m(&self) -> f64 {
        let r = self.radius_m;
        r - libm::sqrt(r * r - self.pitch_m * self.pitch_m / 2.0)
    }
}

/// Sinusoidal grid (§8.5.4, Table 8-5): `z = Ax sin(2πx/λx) + Ay sin(2πy/λy)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinusoidalGrid {
    /// Amplitude along X in m (thesis: 5e-6).
    pub ax_m: f64,
    /// Amplitude along Y in m (thesis: 5e-6).
    pub ay_m: f64,
    /// Wavelength along X in m (thesis: 1e-3).
    pub lambda_x_m: f64,
    /// Wavelength along Y in m (thesis: 1e-3).
    pub lambda_y_m: f64,
}

impl Surface for SinusoidalGrid {
    #[inline]
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        let (x, y) = cartesian(r_m, theta_rad);
        self.ax_m * libm::sin(TAU * x / self.lambda_x_m)
            + self.ay_m * libm::sin(TAU * y / self.lambda_y_m)
    }

    fn peak_m(&self) -> f64 {
        libm::fabs(self.ax_m) + libm::fabs(self.ay_m)
    }
}

/// Single-path micro-lenslets (§8.5.2, Table 8-3): the tool oscillates `n` times per spindle
/// revolution, `z = A sin(nθ)`, cutting at the far end (100 Hz at 16 rpm: n = 375).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MicroLenslet {
    /// Motion amplitude A in m (thesis: 10e-6; the depth of cut is half of it).
    pub amplitude_m: f64,
    /// Oscillations per revolution n.
    pub per_revolution: f64,
}

impl Surface for MicroLenslet {
    #[inline]
    fn depth_m(&self, _r_m: f64, theta_rad: f64) -> f64 {
        self.amplitude_m * libm::sin(self.per_revolution * theta_rad)
    }

    fn peak_m(&self) -> f64 {
        libm::fabs(self.amplitude_m)
    }
}

/// A greyscale height map (§8.5.5): `width × height` pixels of `pixel_m` square, centred on
/// the spindle axis, row 0 at +y; grey 0 → depth 0, 255 → `depth_range_m`; outside the map:
/// 0. Nearest pixel. The pixels are loaded before the run; the tick only reads them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightMap<'a> {
    /// Row-major greyscale pixels, `width · height` of them.
    pub pixels: &'a [u8],
    /// Pixels per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Pixel edge in m.
    pub pixel_m: f64,
    /// Depth of a white pixel in m.
    pub depth_range_m: f64,
}

impl Surface for HeightMap<'_> {
    #[inline]
    fn depth_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        let (x, y) = cartesian(r_m, theta_rad);
        let col = libm::floor(x / self.pixel_m + self.width as f64 / 2.0);
        let row = libm::floor(self.height as f64 / 2.0 - y / self.pixel_m);
        if !(col >= 0.0 && row >= 0.0 && col < self.width as f64 && row < self.height as f64) {
            return 0.0;
        }
        let i = row as usize * self.width + col as usize;
        match self.pixels.get(i) {
            Some(&g) => g as f64 / 255.0 * self.depth_range_m,
            None => 0.0,
        }
    }

    /// A white pixel (or 0 for a negative range).
    fn peak_m(&self) -> f64 {
        self.depth_range_m.max(0.0)
    }
}
