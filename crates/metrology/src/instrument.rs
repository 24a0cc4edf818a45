//! A simulated instrument: a part's surface sampled as an interferometer or a profilometer
//! would return it — on its own pixel grid, the part mounted with a random pose (decentre,
//! rotation about the axis, tilt, piston), each pixel the mean height over its area (the
//! lateral resolution), white noise, no data beyond the part's edge and at random dropouts.

use crate::map::{pixel_points, MapFormat, MeasuredMap, Placement, PIXEL_SUBSAMPLES};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::Serialize;

/// The instrument.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Instrument {
    /// Pixels per side.
    pub pixels: usize,
    /// The field of view over the part's diameter (> 1: a margin for the mounting).
    pub field_over_diameter: f64,
    /// White noise per pixel, m RMS.
    pub noise_m: f64,
    /// The share of pixels on the part that return no data.
    pub dropout: f64,
    /// The largest mounting decentre along x and y, m.
    pub max_decentre_m: f64,
    /// The largest mounting tilt about x and y, rad.
    pub max_tilt_rad: f64,
}

impl Default for Instrument {
    /// A 200 × 200 pixel map over 1.1 part diameters, 0.5 nm RMS noise, 1 % dropouts, the
    /// part mounted within ±0.2 mm and ±50 µrad, at any rotation.
    fn default() -> Self {
        Instrument {
            pixels: 200,
            field_over_diameter: 1.1,
            noise_m: 0.5e-9,
            dropout: 0.01,
            max_decentre_m: 0.2e-3,
            max_tilt_rad: 50e-6,
        }
    }
}

/// The mounting pose a measurement drew (what a registration should find).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mounting {
    /// Piston, m.
    pub piston_m: f64,
    /// Tilt along x and y, rad.
    pub tilt_rad: [f64; 2],
    /// The part's centre in the instrument's frame, m.
    pub decentre_m: [f64; 2],
    /// The part's rotation about the axis, rad.
    pub rotation_rad: f64,
}

impl Instrument {
    /// Measures the part whose height toward the instrument at `(x, y)` in its own frame
    /// (m) is `part(x, y)`, of aperture radius `aperture_m`, mounted with a pose drawn from
    /// `seed`.
    pub fn measure(
        &self,
        part: impl Fn(f64, f64) -> f64,
        aperture_m: f64,
        seed: u64,
    ) -> (MeasuredMap, Mounting) {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut within = |r: f64| r * (2.0 * rng.random::<f64>() - 1.0);
        let pose = Mounting {
            piston_m: within(1e-6),
            tilt_rad: [within(self.max_tilt_rad), within(self.max_tilt_rad)],
            decentre_m: [within(self.max_decentre_m), within(self.max_decentre_m)],
            rotation_rad: within(std::f64::consts::PI),
        };
        let n = self.pixels;
        let pitch = 2.0 * aperture_m * self.field_over_diameter / n as f64;
        let mut map = MeasuredMap {
            rows: n,
            cols: n,
            pitch_m: [pitch; 2],
            heights_m: vec![f64::NAN; n * n],
            format: MapFormat::ZygoXyz,
            wavelength_m: Some(632.8e-9),
        };
        let noise =
            Normal::new(0.0, self.noise_m.max(0.0)).unwrap_or(Normal::new(0.0, 0.0).expect("zero"));
        let placed = Placement::new(pose.decentre_m, pose.rotation_rad);
        for i in 0..n * n {
            let (u0, v0) = map.xy(i);
            let mut sum = 0.0;
            let mut on_part = true;
            for (du, dv) in pixel_points(PIXEL_SUBSAMPLES) {
                let (qx, qy) = placed.part_point(u0 + du * pitch, v0 + dv * pitch);
                if libm::hypot(qx, qy) > aperture_m {
                    on_part = false;
                    break;
                }
                sum += part(qx, qy);
            }
            let dropped = rng.random::<f64>() < self.dropout;
            if on_part && !dropped {
                map.heights_m[i] = sum / (PIXEL_SUBSAMPLES * PIXEL_SUBSAMPLES) as f64
                    + pose.piston_m
                    + pose.tilt_rad[0] * u0
                    + pose.tilt_rad[1] * v0
                    + noise.sample(&mut rng);
            }
        }
        (map, pose)
    }
}
