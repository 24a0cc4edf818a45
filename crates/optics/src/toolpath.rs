//! The fast tool servo's share of a prescription's tool path. The nose-compensated tool
//! height `z_t(r, θ)` ([`super::nose`]) splits into its rotationally symmetric part — the
//! angular mean at each radius, the least-squares best fit of a function of `r` alone, which
//! the Z slide cuts as it feeds — and the rest, which the FTS must move at spindle speed.

use super::nose::{contact, tightness, Contact};
use super::Prescription;

/// Radii of the symmetric part's table over the aperture.
const SYMMETRIC_RADII: usize = 256;

/// Angles averaged per radius of that table.
const SYMMETRIC_ANGLES: usize = 128;

/// Where a compensated contact could not be found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoContact {
    /// Radius of the tool, m.
    pub radius_m: f64,
    /// Spindle angle, rad.
    pub theta_rad: f64,
}

/// A prescription's tool path, split between the Z slide and the FTS.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolPath {
    prescription: Prescription,
    /// Nose radius compensated, m (0: the tool tip follows the surface itself).
    nose_radius_m: f64,
    /// Symmetric part at `i·step_m`, m toward the tool.
    symmetric_m: Vec<f64>,
    step_m: f64,
    /// Highest and lowest FTS height over the sampled aperture, m.
    range_m: (f64, f64),
}

impl ToolPath {
    /// The path of `prescription` for a nose of radius `nose_radius_m` (m; 0 uncompensated),
    /// over its aperture; an error where the nose finds no contact (a concave region tighter
    /// than the nose).
    pub fn new(prescription: Prescription, nose_radius_m: f64) -> Result<Self, NoContact> {
        let aperture = prescription.aperture_radius_m;
        let step_m = aperture / (SYMMETRIC_RADII - 1) as f64;
        let mut path = ToolPath {
            prescription,
            nose_radius_m,
            symmetric_m: Vec::with_capacity(SYMMETRIC_RADII),
            step_m,
            range_m: (f64::INFINITY, f64::NEG_INFINITY),
        };
        let mut rings = Vec::with_capacity(SYMMETRIC_RADII);
        for i in 0..SYMMETRIC_RADII {
            let r = i as f64 * step_m;
            let ring = (0..SYMMETRIC_ANGLES)
                .map(|k| {
                    let theta = k as f64 * std::f64::consts::TAU / SYMMETRIC_ANGLES as f64;
                    path.tip_height_m(r, theta).ok_or(NoContact {
                        radius_m: r,
                        theta_rad: theta,
                    })
                })
                .collect::<Result<Vec<f64>, NoContact>>()?;
            path.symmetric_m
                .push(ring.iter().sum::<f64>() / SYMMETRIC_ANGLES as f64);
            rings.push(ring);
        }
        for (i, ring) in rings.iter().enumerate() {
            for &z in ring {
                let fts = z - path.symmetric_m[i];
                path.range_m = (path.range_m.0.min(fts), path.range_m.1.max(fts));
            }
        }
        Ok(path)
    }

    /// The prescription.
    pub fn prescription(&self) -> &Prescription {
        &self.prescription
    }

    /// The compensated nose radius, m.
    pub fn nose_radius_m(&self) -> f64 {
        self.nose_radius_m
    }

    /// The nose's contact at tool radius `r_m` (m) and spindle angle `theta_rad` (rad).
    pub fn contact(&self, r_m: f64, theta_rad: f64) -> Option<Contact> {
        contact(&self.prescription, self.nose_radius_m, r_m, theta_rad)
    }

    /// `R·κ` at the contact `c` found at spindle angle `theta_rad` (rad): ≥ 1, a concave
    /// region tighter than the nose.
    pub fn tightness(&self, c: &Contact, theta_rad: f64) -> f64 {
        tightness(&self.prescription, self.nose_radius_m, c, theta_rad)
    }

    /// The tool tip's height toward the tool, m (None: no contact).
    pub fn tip_height_m(&self, r_m: f64, theta_rad: f64) -> Option<f64> {
        self.contact(r_m, theta_rad).map(|c| c.tip_height_m)
    }

    /// The height error (m toward the tool; NaN without contact) that tool-setting errors
    /// leave at `(r_m, theta_rad)` on the part: the tool set `centre_height_m` above the
    /// spindle axis and `x_offset_m` further out cuts, when the table stands at radius r, the
    /// point at radius `√((r + e)² + h²)` and angle `θ + atan2(h, r + e)`, leaving there the
    /// height commanded for r (attributed to `(r, θ)`: first order in the errors).
    pub fn setting_error_m(
        &self,
        r_m: f64,
        theta_rad: f64,
        centre_height_m: f64,
        x_offset_m: f64,
    ) -> f64 {
        let tip = |r: f64, theta: f64| self.tip_height_m(r, theta).unwrap_or(f64::NAN);
        let out = r_m + x_offset_m;
        tip(r_m, theta_rad)
            - tip(
                libm::hypot(out, centre_height_m),
                theta_rad + libm::atan2(centre_height_m, out),
            )
    }

    /// The rotationally symmetric part at radius `r_m` (m), m: the table interpolated by
    /// cubic convolution (continuous slope).
    pub fn symmetric_m(&self, r_m: f64) -> f64 {
        let n = self.symmetric_m.len() as isize;
        let u = (r_m / self.step_m).max(0.0);
        let i0 = u.floor();
        let t = u - i0;
        let i0 = i0 as isize;
        // The table is even in r (a function of r alone): mirror it through the axis.
        let at = |i: isize| {
            let i = i.abs();
            if i < n {
                self.symmetric_m[i as usize]
            } else {
                let last = self.symmetric_m[(n - 1) as usize];
                last + (last - self.symmetric_m[(n - 2) as usize]) * (i - n + 1) as f64
            }
        };
        let (w, _) = super::grid::weights(t);
        (0..4).map(|k| w[k] * at(i0 - 1 + k as isize)).sum()
    }

    /// The FTS's height at `(r_m, theta_rad)`, m toward the tool: the tip height less the
    /// symmetric part (where no contact settles, the uncompensated surface stands in).
    pub fn fts_m(&self, r_m: f64, theta_rad: f64) -> f64 {
        self.fts_at(r_m, theta_rad).1
    }

    /// The contact at `(r_m, theta_rad)` and the FTS height it gives ([`ToolPath::fts_m`]),
    /// the contact solved once.
    pub fn fts_at(&self, r_m: f64, theta_rad: f64) -> (Option<Contact>, f64) {
        let contact = self.contact(r_m, theta_rad);
        let tip = contact.map_or_else(
            || {
                -self
                    .prescription
                    .sag(r_m * libm::cos(theta_rad), r_m * libm::sin(theta_rad))
                    .z_m
            },
            |c| c.tip_height_m,
        );
        (contact, tip - self.symmetric_m(r_m))
    }

    /// The cut path's height above the design's at `(x_m, y_m)` in the part's frame, m: the
    /// `compensation` grid's sag (0 without one).
    pub fn compensation_m(&self, x_m: f64, y_m: f64) -> f64 {
        self.prescription
            .compensation
            .as_ref()
            .map_or(0.0, |c| c.sag(x_m, y_m).z_m)
    }

    /// The FTS's lowest and highest height over the aperture (sampled), m.
    pub fn fts_range_m(&self) -> (f64, f64) {
        self.range_m
    }
}
