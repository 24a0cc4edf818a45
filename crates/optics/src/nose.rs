//! Tool-nose radius compensation in the radial section (thesis §9.3.1 names it future work).
//!
//! A round-nose diamond's cutting edge is a circle of radius R in the plane of its rake face,
//! which holds the radial direction and the spindle axis. At spindle angle θ the part's
//! profile along the radius is the height toward the tool `h(r) = −z(r cos θ, r sin θ)` (the
//! tool works on the −z side, where the light meets the surface in Zemax's convention). The
//! nose touches the profile at the contact radius `r_p` where the profile's normal points at
//! the nose centre: `r_t = r_p − R sin α`, `z_t = h(r_p) + R cos α − R`, `tan α = h'(r_p)`, with
//! `(r_t, z_t)` the nose's lowest point (the tool position the servo is commanded to). Without
//! it the part is cut `R(1/cos α − 1)` too deep and `R sin α` off to the side. The contact is
//! unique while the concave curvature stays below 1/R ([`tightness`] < 1).

use super::Prescription;

/// Largest secant steps per contact.
const MAX_STEPS: usize = 60;

/// The contact equation is solved to this, m (0.1 pm).
const TOLERANCE_M: f64 = 1e-13;

/// The nose's contact with the profile at one tool position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// Height of the nose's lowest point (the commanded tool height), m toward the tool.
    pub tip_height_m: f64,
    /// Radius of the contact point, m.
    pub contact_radius_m: f64,
    /// Radial slope at the contact, `dh/dr`.
    pub slope: f64,
}

/// The profile of `p` along the ray at `theta` (rad): `(h, dh/dr)` at signed radius `r` (m).
fn profile(p: &Prescription, r: f64, (c, s): (f64, f64)) -> (f64, f64) {
    let sag = p.sag(r * c, r * s);
    (-sag.z_m, -(sag.dz_dx * c + sag.dz_dy * s))
}

/// The contact of a nose of radius `nose_radius_m` (m) with tip at radius `r_m` (m) and
/// spindle angle `theta_rad` (rad); None when the contact does not settle (a concave region
/// tighter than the nose, or a slope of 90°).
pub fn contact(p: &Prescription, nose_radius_m: f64, r_m: f64, theta_rad: f64) -> Option<Contact> {
    let dir = (libm::cos(theta_rad), libm::sin(theta_rad));
    let big_r = nose_radius_m;
    // f(r_p) = r_p − R sin α(r_p) − r_t = 0, solved by secant from the fixed-point guess.
    let f = |rp: f64| {
        let (_, d) = profile(p, rp, dir);
        rp - big_r * d / (1.0 + d * d).sqrt() - r_m
    };
    let (mut x0, mut f0) = (r_m, f(r_m));
    let mut x1 = r_m - f0;
    for _ in 0..MAX_STEPS {
        let f1 = f(x1);
        if !f1.is_finite() {
            return None;
        }
        if f1.abs() <= TOLERANCE_M {
            let (h, d) = profile(p, x1, dir);
            return Some(Contact {
                tip_height_m: h + big_r / (1.0 + d * d).sqrt() - big_r,
                contact_radius_m: x1,
                slope: d,
            });
        }
        if f1 == f0 {
            return None;
        }
        let x2 = x1 - f1 * (x1 - x0) / (f1 - f0);
        (x0, f0, x1) = (x1, f1, x2);
    }
    None
}

/// `R·κ` at the contact `c` on the ray at `theta_rad` (rad) for a nose of radius
/// `nose_radius_m` (m): the profile's concave curvature κ (from the slope's central difference,
/// a step far below the nose radius) times R; ≥ 1 gouges.
pub fn tightness(p: &Prescription, nose_radius_m: f64, c: &Contact, theta_rad: f64) -> f64 {
    let dir = (libm::cos(theta_rad), libm::sin(theta_rad));
    let step = 1e-6 * nose_radius_m.max(1e-6);
    let (_, d_plus) = profile(p, c.contact_radius_m + step, dir);
    let (_, d_minus) = profile(p, c.contact_radius_m - step, dir);
    let norm = (1.0 + c.slope * c.slope).sqrt();
    nose_radius_m * (d_plus - d_minus) / (2.0 * step) / (norm * norm * norm)
}
