//! Registration of a measured map against the design: a least-squares fit, on the valid pixels
//! over the part, of the terms the instrument and the machine add to the design surface.
//!
//! The map's pixel at `w = (u, v)` (the instrument's frame, m) sees the part at
//! `q = R(−φ)(w − d)` (decentre `d`, rotation `φ` about the axis), so it reads
//!
//! `m(w) = H(q) + p + tₓu + t_y v [+ a·Z₄(q)] [+ h·S_h(q) + e·S_e(q)] + residual`
//!
//! with `H = −sag` the design's height toward the instrument (each pixel its area's mean), piston `p`, tilts `tₓ, t_y`,
//! power `a` (Standard Zernike 4 on the aperture, unit RMS), and the part's error left by a
//! tool centre height `h` and X offset `e` (`S_h`, `S_e`: the errors per metre of each,
//! `optics::toolpath::ToolPath::setting_error_m`). Gauss–Newton from the valid pixels' centroid
//! and a coarse scan of the rotation; the rotation is fitted only where the design is not
//! rotationally symmetric. The standard uncertainties are `s²(JᵀJ)⁻¹` widened by the residual's
//! spatial correlation (the area of its autocorrelation, in pixels): a smooth residual holds
//! fewer independent pixels than it has.

use crate::aperture::ApertureMap;
use crate::form::{form_of, Form};
use crate::map::{pixel_points, MeasuredMap, Placement, PIXEL_SUBSAMPLES};
use nalgebra::{DMatrix, DVector};
use optics::toolpath::ToolPath;
use optics::{Zernike, ZernikeOrder};
use serde::Serialize;

/// The fewest valid pixels on the part a registration accepts.
pub const MIN_VALID_PIXELS: usize = 1000;

/// The most pixels the fit itself uses (an even stride through the valid ones beyond this).
const MAX_FIT_PIXELS: usize = 20_000;

/// The most pixels the residual's form is computed on.
const MAX_FORM_PIXELS: usize = 100_000;

/// Nodes per side of the setting-error signatures' grid.
const SIGNATURE_NODES: usize = 257;

/// The setting error at which the signatures are evaluated, m.
const SIGNATURE_STEP_M: f64 = 1e-6;

/// Rotations tried before Gauss–Newton refines the best (1°: a design with detail a
/// millimetre across at a 10 mm radius still has the best within its basin).
const ROTATION_STEPS: usize = 360;

/// The most pixels the rotation scan uses.
const SCAN_PIXELS: usize = 3000;

/// Largest lag of the residual's autocorrelation, pixels.
const MAX_LAG: usize = 64;

/// What the fit includes beyond piston, tilt and decentre (and rotation where observable).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RegisterOptions {
    /// Fit power (the instrument's focus, or the part's radius error).
    pub power: bool,
    /// Fit the tool's centre height and X offset.
    pub setting_errors: bool,
}

/// A fitted value and its standard uncertainty.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Estimate {
    /// The value.
    pub value: f64,
    /// Its standard uncertainty (1σ).
    pub std: f64,
}

/// What a registration found.
#[derive(Debug, Clone, Serialize)]
pub struct Registration {
    /// Piston, m.
    pub piston_m: Estimate,
    /// Tilt along x and y (height change per length), rad.
    pub tilt_rad: [Estimate; 2],
    /// The part's centre in the instrument's frame, m.
    pub decentre_m: [Estimate; 2],
    /// The part's rotation about the axis in the instrument's frame, rad (None: the design is
    /// rotationally symmetric, so a rotation is not seen).
    pub rotation_rad: Option<Estimate>,
    /// Power, the Standard Zernike 4 coefficient on the aperture, m (None: not fitted).
    pub power_m: Option<Estimate>,
    /// The tool's centre height above the spindle axis, m (None: not fitted).
    pub centre_height_m: Option<Estimate>,
    /// The tool's X offset (cutting further out than commanded), m (None: not fitted).
    pub x_offset_m: Option<Estimate>,
    /// Valid pixels in the map.
    pub pixels_valid: usize,
    /// Valid pixels on the part (within its aperture once registered).
    pub pixels_on_part: usize,
    /// Pixels the fit used.
    pub pixels_fitted: usize,
    /// The share of the part's aperture the valid pixels cover.
    pub aperture_covered: f64,
    /// How much the residual's spatial correlation widens the uncertainties' variances.
    pub variance_inflation: f64,
    /// Gauss–Newton iterations.
    pub iterations: usize,
    /// The design's aperture radius, m.
    pub aperture_m: f64,
    /// The residual's form on the part's aperture (part's frame).
    pub residual: Form,
    /// The residual on the map's grid, m (NaN off the part or without data).
    #[serde(skip)]
    pub residual_map: MeasuredMap,
}

/// Why a map cannot be registered.
#[derive(Debug, Clone, PartialEq)]
pub struct RegisterError(pub String);

/// The setting-error signatures over the aperture (and a margin beyond it, so that
/// interpolation at its edge has neighbours), per metre of error: centre height, X offset.
fn signatures(path: &ToolPath) -> [ApertureMap; 2] {
    let half = path.prescription().aperture_radius_m * 1.05;
    let map = |h: f64, e: f64| {
        ApertureMap::of(SIGNATURE_NODES, half, |x, y| {
            let v =
                path.setting_error_m(libm::hypot(x, y), libm::atan2(y, x), h, e) / SIGNATURE_STEP_M;
            if v.is_finite() {
                v
            } else {
                0.0
            }
        })
    };
    [map(SIGNATURE_STEP_M, 0.0), map(0.0, SIGNATURE_STEP_M)]
}

/// The fit's unknowns, in the order of the Jacobian's columns.
#[derive(Debug, Clone, Copy)]
struct Pose {
    linear: [f64; 6],
    d: [f64; 2],
    phi: f64,
}

/// Which columns the fit carries.
#[derive(Debug, Clone, Copy)]
struct Columns {
    power: bool,
    setting: bool,
    rotation: bool,
}

impl Columns {
    /// The linear terms' flags: piston, tilt x, tilt y, power, centre height, X offset.
    fn linear(&self) -> [bool; 6] {
        [true, true, true, self.power, self.setting, self.setting]
    }
    fn count(&self) -> usize {
        self.linear().iter().filter(|b| **b).count() + 2 + usize::from(self.rotation)
    }
}

/// The design and what the model needs of it.
struct Model<'a> {
    path: &'a ToolPath,
    /// The map's pixel pitch, m.
    pitch_m: [f64; 2],
    /// Points per side a pixel's design is the mean of (1: its centre).
    subsamples: usize,
    aperture_m: f64,
    power: Zernike,
    signatures: Option<[ApertureMap; 2]>,
}

/// One pixel's model value and Jacobian row (all nine columns), None off the part: the
/// design is the mean over the pixel's area ([`PIXEL_SUBSAMPLES`]² points, as an instrument's
/// pixel integrates it), the smooth terms at its centre.
fn evaluate(m: &Model, pose: &Pose, u: f64, v: f64) -> Option<(f64, [f64; 9])> {
    let placed = Placement::new(pose.d, pose.phi);
    let n = m.subsamples;
    let (mut h, mut hx, mut hy, mut turn) = (0.0, 0.0, 0.0, 0.0);
    for (du, dv) in pixel_points(n) {
        let (qx, qy) = placed.part_point(u + du * m.pitch_m[0], v + dv * m.pitch_m[1]);
        if libm::hypot(qx, qy) > m.aperture_m {
            return None;
        }
        let sag = m.path.prescription().sag(qx, qy);
        h -= sag.z_m;
        hx -= sag.dz_dx;
        hy -= sag.dz_dy;
        turn -= sag.dz_dx * qy - sag.dz_dy * qx;
    }
    let count = (n * n) as f64;
    let (h, hx, hy, turn) = (h / count, hx / count, hy / count, turn / count);
    let (qx, qy) = placed.part_point(u, v);
    let z4 = m.power.basis(4, qx, qy).z_m;
    let (sh, se) = m
        .signatures
        .as_ref()
        .map_or((0.0, 0.0), |[h, e]| (h.at(qx, qy), e.at(qx, qy)));
    let basis = [1.0, u, v, z4, sh, se];
    let value = h + basis
        .iter()
        .zip(&pose.linear)
        .map(|(b, k)| b * k)
        .sum::<f64>();
    let [dx, dy] = placed.decentre_sensitivity(hx, hy);
    let row = [
        basis[0], basis[1], basis[2], basis[3], basis[4], basis[5], dx, dy, turn,
    ];
    Some((value, row))
}

/// The columns kept, as indices into the nine.
fn kept(cols: &Columns) -> Vec<usize> {
    let lin = cols.linear();
    (0..9)
        .filter(|&k| match k {
            0..=5 => lin[k],
            6 | 7 => true,
            _ => cols.rotation,
        })
        .collect()
}

/// Normal equations over `pixels`: `(JᵀJ, Jᵀr, Σr², pixels on the part)`.
fn normal(
    m: &Model,
    pose: &Pose,
    pixels: &[(f64, f64, f64)],
    keep: &[usize],
) -> (DMatrix<f64>, DVector<f64>, f64, usize) {
    let k = keep.len();
    let mut jtj = DMatrix::zeros(k, k);
    let mut jtr = DVector::zeros(k);
    let (mut ss, mut n) = (0.0, 0);
    for &(u, v, h) in pixels {
        if let Some((value, row)) = evaluate(m, pose, u, v) {
            let r = h - value;
            for (a, &ka) in keep.iter().enumerate() {
                jtr[a] += row[ka] * r;
                for (b, &kb) in keep.iter().enumerate().skip(a) {
                    jtj[(a, b)] += row[ka] * row[kb];
                }
            }
            ss += r * r;
            n += 1;
        }
    }
    for a in 0..k {
        for b in 0..a {
            jtj[(a, b)] = jtj[(b, a)];
        }
    }
    (jtj, jtr, ss, n)
}

/// `(JᵀJ)⁻¹` by column scaling and SVD (None: singular).
fn inverse(jtj: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let k = jtj.nrows();
    let scale = DVector::from_fn(k, |i, _| {
        let d = jtj[(i, i)];
        if d > 0.0 {
            1.0 / d.sqrt()
        } else {
            1.0
        }
    });
    let scaled = DMatrix::from_fn(k, k, |i, j| jtj[(i, j)] * scale[i] * scale[j]);
    let svd = scaled.svd(true, true);
    if svd.singular_values.min() < 1e-12 * svd.singular_values.max() {
        return None;
    }
    let inv = svd.pseudo_inverse(0.0).ok()?;
    Some(DMatrix::from_fn(k, k, |i, j| {
        inv[(i, j)] * scale[i] * scale[j]
    }))
}

/// Registers `map` against the design of `path` (its prescription without compensation).
pub fn register(
    map: &MeasuredMap,
    path: &ToolPath,
    options: &RegisterOptions,
) -> Result<Registration, RegisterError> {
    let aperture = path.prescription().aperture_radius_m;
    let valid = map.valid();
    let area = map.pitch_m[0] * map.pitch_m[1];
    let equivalent = (valid.len() as f64 * area / std::f64::consts::PI).sqrt();
    if valid.len() < MIN_VALID_PIXELS {
        return Err(RegisterError(format!(
            "too few valid pixels: {} (at least {MIN_VALID_PIXELS})",
            valid.len()
        )));
    }
    if !(0.3 * aperture..=1.1 * aperture).contains(&equivalent) {
        return Err(RegisterError(format!(
            "a map of another aperture: its valid pixels cover a disc of radius {:.3} mm, the design's aperture is {:.3} mm (a map covering 30 % … 110 % of that radius is registered)",
            equivalent * 1e3,
            aperture * 1e3
        )));
    }
    let model = Model {
        path,
        pitch_m: map.pitch_m,
        subsamples: PIXEL_SUBSAMPLES,
        aperture_m: aperture,
        power: Zernike {
            order: ZernikeOrder::Standard,
            norm_radius_m: aperture,
            coefficients_m: Vec::new(),
        },
        signatures: options.setting_errors.then(|| signatures(path)),
    };
    let stride = valid.len().div_ceil(MAX_FIT_PIXELS);
    let fit: Vec<(f64, f64, f64)> = valid.iter().step_by(stride).copied().collect();
    let n = valid.len() as f64;
    let centroid = [
        valid.iter().map(|p| p.0).sum::<f64>() / n,
        valid.iter().map(|p| p.1).sum::<f64>() / n,
    ];
    let rotation = rotation_observable(path, aperture);
    let cols = Columns {
        power: options.power,
        setting: options.setting_errors,
        rotation,
    };
    let mut pose = Pose {
        linear: [0.0; 6],
        d: centroid,
        phi: 0.0,
    };
    if rotation {
        pose.phi = coarse_rotation(&model, &pose, &fit);
    }
    // Gauss–Newton.
    let mut iterations = 0;
    let keep = kept(&cols);
    for _ in 0..50 {
        iterations += 1;
        let (jtj, jtr, _, used) = normal(&model, &pose, &fit, &keep);
        if used < cols.count() * 10 {
            return Err(RegisterError(format!(
                "only {used} pixels fall on the part once placed (the map and the design do not overlap)"
            )));
        }
        let inv = inverse(&jtj).ok_or_else(|| {
            RegisterError("the fit is singular: the terms asked for cannot be told apart on this design and map (drop power or the setting errors)".into())
        })?;
        let step = inv * jtr;
        let mut shift: f64 = 0.0;
        for (a, &k) in keep.iter().enumerate() {
            match k {
                0..=5 => pose.linear[k] += step[a],
                6 | 7 => {
                    let s = step[a].clamp(-0.1 * aperture, 0.1 * aperture);
                    pose.d[k - 6] += s;
                    shift = shift.max(s.abs() / aperture);
                }
                _ => {
                    let s = step[a].clamp(-0.1, 0.1);
                    pose.phi += s;
                    shift = shift.max(s.abs());
                }
            }
        }
        if shift < 1e-9 {
            break;
        }
    }
    // The residual over every valid pixel on the part.
    let mut residual_map = map.clone();
    residual_map.heights_m.fill(f64::NAN);
    let mut on_part = Vec::new();
    for (i, &h) in map.heights_m.iter().enumerate() {
        if !h.is_finite() {
            continue;
        }
        let (u, v) = map.xy(i);
        if let Some((value, _)) = evaluate(&model, &pose, u, v) {
            residual_map.heights_m[i] = h - value;
            on_part.push(i);
        }
    }
    let (jtj, _, ss, used) = normal(&model, &pose, &fit, &keep);
    let dof = (used.saturating_sub(keep.len())).max(1) as f64;
    let inflation =
        (correlation_area(&residual_map) * used as f64 / on_part.len().max(1) as f64).max(1.0);
    let cov = inverse(&jtj)
        .ok_or_else(|| RegisterError("the fit is singular at its solution".into()))?
        * (ss / dof * inflation);
    let estimate = |k: usize| -> Option<Estimate> {
        keep.iter().position(|&c| c == k).map(|a| Estimate {
            value: match k {
                0..=5 => pose.linear[k],
                6 | 7 => pose.d[k - 6],
                // Within (−π, π].
                _ => {
                    std::f64::consts::PI
                        - (std::f64::consts::PI - pose.phi).rem_euclid(std::f64::consts::TAU)
                }
            },
            std: cov[(a, a)].max(0.0).sqrt(),
        })
    };
    let none = Estimate {
        value: 0.0,
        std: 0.0,
    };
    let stride = on_part.len().div_ceil(MAX_FORM_PIXELS).max(1);
    let placed = Placement::new(pose.d, pose.phi);
    let points: Vec<(f64, f64, f64)> = on_part
        .iter()
        .step_by(stride)
        .map(|&i| {
            let (u, v) = map.xy(i);
            let (x, y) = placed.part_point(u, v);
            (x, y, residual_map.heights_m[i])
        })
        .collect();
    let covered = on_part.len() as f64 * area / (std::f64::consts::PI * aperture * aperture);
    Ok(Registration {
        piston_m: estimate(0).unwrap_or(none),
        tilt_rad: [estimate(1).unwrap_or(none), estimate(2).unwrap_or(none)],
        decentre_m: [estimate(6).unwrap_or(none), estimate(7).unwrap_or(none)],
        rotation_rad: estimate(8),
        power_m: estimate(3),
        centre_height_m: estimate(4),
        x_offset_m: estimate(5),
        pixels_valid: valid.len(),
        pixels_on_part: on_part.len(),
        pixels_fitted: used,
        aperture_covered: covered.min(1.0),
        variance_inflation: inflation,
        iterations,
        aperture_m: aperture,
        residual: form_of(&points, aperture),
        residual_map,
    })
}

/// Whether turning the design about its axis changes it (≥ 1 nm RMS per rad over the
/// aperture): a rotationally symmetric design does not show a rotation.
fn rotation_observable(path: &ToolPath, aperture: f64) -> bool {
    let mut ss = 0.0;
    let mut n = 0;
    for i in 1..=16 {
        let r = aperture * i as f64 / 16.0;
        for k in 0..64 {
            let t = k as f64 * std::f64::consts::TAU / 64.0;
            let (x, y) = (r * libm::cos(t), r * libm::sin(t));
            let s = path.prescription().sag(x, y);
            let d = -y * s.dz_dx + x * s.dz_dy;
            ss += d * d;
            n += 1;
        }
    }
    (ss / n as f64).sqrt() > 1e-9
}

/// The rotation, among [`ROTATION_STEPS`] around the circle, whose linear fit (piston, tilt)
/// leaves the least residual at the starting decentre.
fn coarse_rotation(m: &Model, start: &Pose, fit: &[(f64, f64, f64)]) -> f64 {
    // Pixels as points: a scan needs the basin, not the last nanometre.
    let m = &Model {
        path: m.path,
        pitch_m: m.pitch_m,
        subsamples: 1,
        aperture_m: m.aperture_m,
        power: m.power.clone(),
        signatures: None,
    };
    let keep = [0, 1, 2];
    let fit: Vec<(f64, f64, f64)> = fit
        .iter()
        .step_by(fit.len().div_ceil(SCAN_PIXELS).max(1))
        .copied()
        .collect();
    let fit = fit.as_slice();
    (0..ROTATION_STEPS)
        .map(|k| {
            let pose = Pose {
                phi: k as f64 * std::f64::consts::TAU / ROTATION_STEPS as f64,
                ..*start
            };
            let (jtj, jtr, ss, n) = normal(m, &pose, fit, &keep);
            let explained = inverse(&jtj).map_or(0.0, |inv| (jtr.transpose() * inv * &jtr)[0]);
            let rms = if n > 0 {
                (ss - explained) / n as f64
            } else {
                f64::INFINITY
            };
            (pose.phi, rms)
        })
        .fold(
            (0.0, f64::INFINITY),
            |best, c| if c.1 < best.1 { c } else { best },
        )
        .0
}

/// The residual's autocorrelation area in pixels: the product of its sums along rows and
/// columns (each summed over lags up to the first that is not positive, at most [`MAX_LAG`]);
/// 1 for white noise.
fn correlation_area(r: &MeasuredMap) -> f64 {
    let h = &r.heights_m;
    let valid: Vec<f64> = h.iter().copied().filter(|v| v.is_finite()).collect();
    if valid.is_empty() {
        return 1.0;
    }
    let mean = valid.iter().sum::<f64>() / valid.len() as f64;
    let var = valid.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / valid.len() as f64;
    if var <= 0.0 {
        return 1.0;
    }
    let sum_along = |step: usize, count: usize| {
        let mut total = 1.0;
        for lag in 1..=MAX_LAG.min(count.saturating_sub(1)) {
            let (mut s, mut n) = (0.0, 0usize);
            for (i, a) in h.iter().enumerate() {
                let j = i + lag * step;
                let same_line = if step == 1 {
                    i / r.cols == j / r.cols
                } else {
                    true
                };
                if j < h.len() && same_line && a.is_finite() && h[j].is_finite() {
                    s += (a - mean) * (h[j] - mean);
                    n += 1;
                }
            }
            let rho = if n > 0 { s / n as f64 / var } else { 0.0 };
            if rho <= 0.0 {
                break;
            }
            total += 2.0 * rho;
        }
        total
    };
    sum_along(1, r.cols) * sum_along(r.cols, r.rows)
}

impl Registration {
    /// The residual in the part's frame on a `nodes × nodes` grid over its aperture: the
    /// measured residual interpolated (bilinear) where its four neighbouring pixels have data,
    /// else its Standard Zernike fit ([`Form::zernike_standard_m`]): a map the next cut's
    /// compensation can be made from.
    pub fn part_map(&self, nodes: usize) -> ApertureMap {
        let placed = Placement::new(
            [self.decentre_m[0].value, self.decentre_m[1].value],
            self.rotation_rad.map_or(0.0, |r| r.value),
        );
        let fit = Zernike {
            order: ZernikeOrder::Standard,
            norm_radius_m: self.aperture_m,
            coefficients_m: self.residual.zernike_standard_m.clone(),
        };
        ApertureMap::of(nodes, self.aperture_m, |x, y| {
            let (u, v) = placed.instrument_point(x, y);
            let measured = self.residual_map.at(u, v);
            if measured.is_finite() {
                measured
            } else {
                fit.sag(x, y).z_m
            }
        })
    }
}
