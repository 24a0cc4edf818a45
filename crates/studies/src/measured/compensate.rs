//! The next cut's compensation from a registered measurement: the previous compensation plus
//! the measured residual (in the part's frame), scaled by a gain and smoothed by a Gaussian
//! low-pass, node by node — then the tool path regenerated with it and checked against the
//! stage before anything is cut; and a stopping rule, for when a cycle no longer helps.

use super::PART_NODES;
use crate::error::StudyError;
use crate::toolpath::{self, ToolpathStudy};
use metrology::{form_of, ApertureMap, Form, ReadOptions};
use optics::toolpath::ToolPath;
use optics::Prescription;
use run_config::surface::LoadedSurface;
use runner::Plan;
use serde::Serialize;
use std::path::Path;

/// A cycle stops helping when its residual's RMS falls by less than this fraction.
pub const MIN_IMPROVEMENT: f64 = 0.1;

/// How the residual enters the next compensation: keys `gain` and `lowpass_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CompensationOptions {
    /// The share of the residual added, (0, 1.5] (1: all of it).
    pub gain: f64,
    /// Standard deviation of the Gaussian low-pass applied to the residual, m (0: none; at most
    /// a quarter of the aperture's radius).
    pub lowpass_m: f64,
}

/// What a cycle found and what it asks for.
#[derive(Debug, Clone, Serialize)]
pub struct NextCompensation {
    /// The residual file (the part's frame: `servo register`'s `part_error.csv`).
    pub residual_file: String,
    /// The options.
    pub options: CompensationOptions,
    /// The residual's form.
    pub residual: Form,
    /// The previous residual's form, when given.
    pub previous_residual: Option<Form>,
    /// Whether the cycle no longer helps: the residual's RMS after piston and tilt fell by
    /// less than [`MIN_IMPROVEMENT`] of the previous one's.
    pub stop: bool,
    /// The previous compensation's form (None: there was none).
    pub previous: Option<Form>,
    /// The next compensation's form.
    pub next: Form,
    /// The tool path with the next compensation: the stage's demands and the predicted part.
    pub toolpath: ToolpathStudy,
    /// The next compensation, m toward the tool (part − design, as a measurement reports it).
    #[serde(skip)]
    pub next_map: ApertureMap,
}

/// `map` smoothed by a Gaussian of standard deviation `sigma_m` (m) over the nodes with a
/// value (normalised: the aperture's edge is not pulled toward zero).
fn lowpass(map: &ApertureMap, sigma_m: f64) -> ApertureMap {
    if sigma_m <= 0.0 {
        return map.clone();
    }
    let n = map.nodes as isize;
    let s = sigma_m / map.pitch_m;
    let reach = (3.0 * s).ceil() as isize;
    let mut out = map.clone();
    for (i, v) in out.values.iter_mut().enumerate() {
        if !v.is_finite() {
            continue;
        }
        let (row, col) = ((i as isize) / n, (i as isize) % n);
        let (mut sum, mut weight) = (0.0, 0.0);
        for dr in -reach..=reach {
            for dc in -reach..=reach {
                let (r, c) = (row + dr, col + dc);
                if r < 0 || c < 0 || r >= n || c >= n {
                    continue;
                }
                let value = map.values[(r * n + c) as usize];
                if value.is_finite() {
                    let w = libm::exp(-((dr * dr + dc * dc) as f64) / (2.0 * s * s));
                    sum += w * value;
                    weight += w;
                }
            }
        }
        *v = sum / weight;
    }
    out
}

/// The residual in `file`, on the part's grid of `aperture_m` (an error naming the file when
/// it does not cover the aperture).
fn residual_on_grid(file: &Path, aperture_m: f64) -> Result<ApertureMap, StudyError> {
    let m = metrology::read_map(file, &ReadOptions::default())?;
    let half = [
        m.pitch_m[0] * (m.cols - 1) as f64 / 2.0,
        m.pitch_m[1] * (m.rows - 1) as f64 / 2.0,
    ];
    if half[0] < aperture_m * (1.0 - 1e-6) || half[1] < aperture_m * (1.0 - 1e-6) {
        return Err(StudyError::Registration {
            path: file.to_path_buf(),
            reason: format!(
                "a map of another aperture: it spans ±{:.4} × ±{:.4} mm, the design's aperture is ±{:.4} mm (a part-frame residual as servo register writes it)",
                half[0] * 1e3,
                half[1] * 1e3,
                aperture_m * 1e3
            ),
        });
    }
    Ok(ApertureMap::of(PART_NODES, aperture_m, |x, y| m.at(x, y)))
}

/// The next compensation of `plan`'s prescription (its `[compensation]`, if any, is the
/// previous one) from the residual in `residual_file`, checked with the tool path over
/// `bands` radius bands; `previous_residual_file`, the previous cycle's residual, decides
/// the stopping rule.
pub fn next_compensation(
    plan: &Plan,
    residual_file: &Path,
    previous_residual_file: Option<&Path>,
    options: &CompensationOptions,
    bands: usize,
) -> Result<NextCompensation, StudyError> {
    let (_, path, _) = toolpath::demands::prescription_of(plan)?;
    let aperture = path.prescription().aperture_radius_m;
    if !(options.gain > 0.0 && options.gain <= 1.5) {
        return Err(plan.origin.invalid("gain", options.gain, "(0, 1.5]").into());
    }
    if !(options.lowpass_m >= 0.0 && options.lowpass_m <= aperture / 4.0) {
        return Err(plan
            .origin
            .invalid(
                "lowpass_m",
                options.lowpass_m,
                &format!(
                    "[0, {}] m: a quarter of the aperture's radius",
                    aperture / 4.0
                ),
            )
            .into());
    }
    let residual = residual_on_grid(residual_file, aperture)?;
    let previous_residual = previous_residual_file
        .map(|f| residual_on_grid(f, aperture).map(|m| form_of(&m.points(), aperture)))
        .transpose()?;
    let filtered = lowpass(&residual, options.lowpass_m);
    // The compensation holds the error as a measurement reports it (part − design, height
    // toward the tool); the path is moved by its negative.
    let has_previous = path.prescription().compensation.is_some();
    let previous = ApertureMap::of(PART_NODES, aperture, |x, y| -path.compensation_m(x, y));
    let next_map = ApertureMap {
        values: previous
            .values
            .iter()
            .zip(&filtered.values)
            .map(|(p, r)| p + options.gain * r)
            .collect(),
        ..previous.clone()
    };
    let next_path = ToolPath::new(
        Prescription {
            compensation: Some(next_map.to_sag_grid()),
            ..path.prescription().clone()
        },
        path.nose_radius_m(),
    )
    .map_err(|e| StudyError::Registration {
        path: residual_file.to_path_buf(),
        reason: format!(
            "the compensated surface is tighter than the nose at r = {:.4} mm: lower the gain or raise the low-pass",
            e.radius_m * 1e3
        ),
    })?;
    let mut next_plan = plan.clone();
    next_plan.surface = Some(LoadedSurface::Prescription(Box::new(next_path)));
    let residual_form = form_of(&residual.points(), aperture);
    let stop = previous_residual.as_ref().is_some_and(|p| {
        residual_form.tilt_removed.rms_m > (1.0 - MIN_IMPROVEMENT) * p.tilt_removed.rms_m
    });
    Ok(NextCompensation {
        residual_file: residual_file.display().to_string(),
        options: *options,
        residual: residual_form,
        previous_residual,
        stop,
        previous: has_previous.then(|| form_of(&previous.points(), aperture)),
        next: form_of(&next_map.points(), aperture),
        toolpath: toolpath::study(&next_plan, bands)?,
        next_map,
    })
}
