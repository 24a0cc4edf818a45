//! The part a prescription's tool path would leave, before it is cut: the stage's demands per
//! radius band ([`demands`]), and over the whole aperture the predicted form error —
//! the run's loop applied to the FTS path ring by ring, each point of the part taking the
//! error of the nose that touched it (the envelope of the nose positions, to first order) —
//! reported as an optician does: PV and RMS after piston and tilt (and after power), Zernike
//! coefficients, a sag grid that can be loaded back to compensate the next cut; and the
//! geometric sensitivity to the tool's centre height and X offset.

pub mod demands;
mod files;

use crate::error::StudyError;
use demands::{feasibility, prescription_of, Feasibility, RingLoop, RING_SAMPLES};
use optics::toolpath::ToolPath;
use runner::Plan;
use serde::Serialize;
use std::f64::consts::TAU;

pub use files::{write_data, TableSize};
pub use metrology::{ApertureMap, Form, Residual};

/// Grid nodes per side of the aperture's maps.
pub const MAP_NODES: usize = 129;

/// Rings of the predicted error from the edge to the axis.
const RINGS: usize = 64;

/// The size of the tool-setting errors whose effect is reported, m.
pub const SETTING_ERROR_M: f64 = 1e-6;

/// One tool-setting error's effect on the part (geometry alone).
#[derive(Debug, Clone, Serialize)]
pub struct Sensitivity {
    /// Which error.
    pub error: String,
    /// Its size, m.
    pub size_m: f64,
    /// The part's form error it makes.
    pub form: Form,
}

/// The whole study.
#[derive(Debug, Clone, Serialize)]
pub struct ToolpathStudy {
    /// The stage's demands per band.
    pub feasibility: Feasibility,
    /// The predicted form error on the part (part − design, height toward the tool; with a
    /// `[compensation]`, against the design without it).
    pub form: Form,
    /// Centre height and X offset of the tool.
    pub sensitivity: Vec<Sensitivity>,
    /// The FTS path over the aperture, m.
    #[serde(skip)]
    pub fts_map: ApertureMap,
    /// The predicted form error over the aperture, m.
    #[serde(skip)]
    pub error_map: ApertureMap,
}

/// `map`'s form on the aperture.
fn form_of(map: &ApertureMap, aperture_m: f64) -> Form {
    metrology::form_of(&map.points(), aperture_m)
}

/// The predicted error, ring by ring: each ring's contact radii and errors at the
/// [`RING_SAMPLES`] angles, ring 0 at the aperture's edge.
fn predicted_rings(path: &ToolPath, ring_loop: &RingLoop) -> Vec<(Vec<f64>, Vec<f64>)> {
    let aperture = path.prescription().aperture_radius_m;
    (0..RINGS)
        .map(|i| {
            let r = aperture * (1.0 - i as f64 / (RINGS - 1) as f64);
            let (contacts, heights): (Vec<f64>, Vec<f64>) = (0..RING_SAMPLES)
                .map(|k| {
                    let (contact, fts) = path.fts_at(r, k as f64 * TAU / RING_SAMPLES as f64);
                    (contact.map_or(r, |c| c.contact_radius_m.abs()), fts)
                })
                .unzip();
            (contacts, ring_loop.predicted_error(&heights))
        })
        .collect()
}

/// The error at radius `rho` along angle sample `k`: linear between the rings whose
/// contacts bracket it (the nearest ring beyond them).
fn along(rings: &[(Vec<f64>, Vec<f64>)], k: usize, rho: f64) -> f64 {
    for w in rings.windows(2) {
        let (outer, inner) = (&w[0], &w[1]);
        let (ro, ri) = (outer.0[k], inner.0[k]);
        if rho <= ro && rho >= ri {
            let t = if ro > ri { (rho - ri) / (ro - ri) } else { 0.0 };
            return inner.1[k] + t * (outer.1[k] - inner.1[k]);
        }
    }
    if rho > rings[0].0[k] {
        rings[0].1[k]
    } else {
        rings[rings.len() - 1].1[k]
    }
}

/// The part `path` leaves through `ring_loop`: its error against the design at `(x, y)` in
/// the part's frame, m toward the tool (the loop's error each point's nose contact took, and a
/// `[compensation]`'s move of the path).
pub fn predicted_part<'a>(
    path: &'a ToolPath,
    ring_loop: &RingLoop,
) -> impl Fn(f64, f64) -> f64 + 'a {
    let rings = predicted_rings(path, ring_loop);
    let step = TAU / RING_SAMPLES as f64;
    move |x, y| {
        let theta = libm::atan2(y, x).rem_euclid(TAU);
        let rho = libm::hypot(x, y);
        let u = theta / step;
        let k = (u.floor() as usize) % RING_SAMPLES;
        let t = u - u.floor();
        let next = (k + 1) % RING_SAMPLES;
        // The part against the design: a [compensation] moved the path off it.
        (1.0 - t) * along(&rings, k, rho) + t * along(&rings, next, rho) + path.compensation_m(x, y)
    }
}

/// Runs the study on `plan` (a machining run of a prescription) with `bands` radius bands.
pub fn study(plan: &Plan, bands: usize) -> Result<ToolpathStudy, StudyError> {
    let feasibility = feasibility(plan, bands)?;
    let (m, path, _) = prescription_of(plan)?;
    let aperture = path.prescription().aperture_radius_m;
    let ring_loop = RingLoop::new(plan, m.rad_per_s() / TAU);
    let error_map = ApertureMap::of(MAP_NODES, aperture, predicted_part(path, &ring_loop));
    let fts_map = ApertureMap::of(MAP_NODES, aperture, |x, y| {
        path.fts_m(libm::hypot(x, y), libm::atan2(y, x))
    });
    let form = form_of(&error_map, aperture);
    let h = SETTING_ERROR_M;
    let centre_height = ApertureMap::of(MAP_NODES, aperture, |x, y| {
        path.setting_error_m(libm::hypot(x, y), libm::atan2(y, x), h, 0.0)
    });
    let x_offset = ApertureMap::of(MAP_NODES, aperture, |x, y| {
        path.setting_error_m(libm::hypot(x, y), libm::atan2(y, x), 0.0, h)
    });
    let sensitivity = vec![
        Sensitivity {
            error: "tool centre height".into(),
            size_m: h,
            form: form_of(&centre_height, aperture),
        },
        Sensitivity {
            error: "tool X offset".into(),
            size_m: h,
            form: form_of(&x_offset, aperture),
        },
    ];
    Ok(ToolpathStudy {
        feasibility,
        form,
        sensitivity,
        fts_map,
        error_map,
    })
}
