//! Before a prescription is cut: what its tool path asks of the stage, radius band by radius
//! band, at the configured spindle speed — the FTS stroke, the peak velocity, acceleration
//! and DAC voltage, the predicted form error through the run's own closed loop and reference
//! path (feedback alone, or with the configured feedforward), the surface's slope along the
//! cut against the tool's clearance angle and the concave curvature against the nose — and
//! the FTS command table a machine's own controller would play (encoder count → height).
//!
//! Each band is sampled around whole revolutions at its radii; the path's harmonics `Xₙ` of
//! the spindle frequency Ω give the velocity `jnΩ·Xₙ`, acceleration `−n²Ω²·Xₙ`, the DAC
//! voltage `V(jnΩ)·Xₙ` and the tool error `(T(jnΩ) − 1)·Xₙ`, with `V` and `T` the loop's
//! responses from the surface reference to the DAC command and to the true tool position.

use loop_model::closed_loop::{output, reference_path_response};
use num_complex::Complex64 as C;
use optics::toolpath::ToolPath;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use run_config::surface::LoadedSurface;
use run_config::{Machining, Scenario, SurfaceConfig};
use runner::{Plan, RunError};
use serde::Serialize;
use std::f64::consts::TAU;
use std::sync::Arc;

/// Samples per revolution of each evaluated ring.
pub const RING_SAMPLES: usize = 2048;

/// Rings evaluated per band (its outer edge first).
const RINGS_PER_BAND: usize = 4;

/// One radius band's demands.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Band {
    /// Inner and outer radius, m.
    pub radius_m: [f64; 2],
    /// FTS stroke (highest − lowest height), m.
    pub stroke_m: f64,
    /// Largest |FTS height| from the ring's angular mean (the flexure's rest), m.
    pub peak_height_m: f64,
    /// Peak FTS velocity, m/s.
    pub peak_velocity_m_per_s: f64,
    /// Peak FTS acceleration, m/s².
    pub peak_acceleration_m_per_s2: f64,
    /// Peak DAC command the loop would send to follow it, V.
    pub peak_voltage_v: f64,
    /// Frequency below which 99.9 % of the path's motion (mean square) lies, Hz.
    pub bandwidth_hz: f64,
    /// Predicted RMS of the tool error (tool − path) at steady state, m.
    pub predicted_rms_m: f64,
    /// Steepest slope along the cut (the tool's flank must clear it), rad.
    pub slope_along_cut_rad: f64,
    /// Largest nose radius × concave curvature in the radial section (≥ 1: the nose cannot
    /// reach the bottom).
    pub nose_tightness: f64,
}

/// What a prescription's tool path asks of the stage, and what exceeds it.
#[derive(Debug, Clone, Serialize)]
pub struct Feasibility {
    /// Spindle speed, rpm.
    pub spindle_rpm: f64,
    /// Compensated nose radius, m (0: uncompensated).
    pub nose_radius_m: f64,
    /// Travel of the Z slide over the aperture (the symmetric part's range), m.
    pub z_slide_travel_m: f64,
    /// FTS stroke over the whole aperture, m.
    pub fts_stroke_m: f64,
    /// The bands, outermost first.
    pub bands: Vec<Band>,
    /// The servo's Nyquist frequency, Hz (path content above it aliases).
    pub nyquist_hz: f64,
    /// DAC full scale, V.
    pub dac_range_v: f64,
    /// Largest |height| the gap sensor reads before its ADC clips (or the protection's
    /// position limit, if smaller), m.
    pub measurable_m: f64,
    /// FTS height where the cut starts (`start_radius_m`, angle 0), m.
    pub start_height_m: f64,
    /// The protection's following-error trip, m (0: off).
    pub following_error_limit_m: f64,
    /// The tool's clearance angle, rad.
    pub clearance_angle_rad: f64,
    /// What exceeds a limit, one sentence each (empty: feasible).
    pub exceeded: Vec<String>,
}

/// The run's loop at the harmonics of the spindle frequency: what a ring of
/// [`RING_SAMPLES`] path heights becomes (predicted tool error, DAC command, derivatives).
pub struct RingLoop {
    /// `T(jnΩ) − 1`, the tool error per metre of path at harmonic n.
    tool_error: Vec<C>,
    /// The DAC command per metre of path at harmonic n, V/m.
    dac: Vec<C>,
    forward: Arc<dyn RealToComplex<f64>>,
    inverse: Arc<dyn ComplexToReal<f64>>,
}

impl RingLoop {
    /// The loop of `plan` (its reference path and closed loop) at a spindle turning at
    /// `spindle_hz` Hz.
    pub fn new(plan: &Plan, spindle_hz: f64) -> Self {
        Self::of(&plan.closed_loop, plan, spindle_hz)
    }

    /// The loop `closed_loop` (a stage's sampled loop with `plan`'s controller) with `plan`'s
    /// reference path (its feedforward) at a spindle turning at `spindle_hz` Hz.
    pub fn of(
        closed_loop: &loop_model::closed_loop::ClosedLoop,
        plan: &Plan,
        spindle_hz: f64,
    ) -> Self {
        let tool = reference_path_response(closed_loop, &plan.deployment, output::TOOL_M);
        let dac = reference_path_response(closed_loop, &plan.deployment, output::CONTROL_V);
        let harmonics = 0..=RING_SAMPLES / 2;
        let mut planner = RealFftPlanner::<f64>::new();
        RingLoop {
            tool_error: harmonics
                .clone()
                .map(|n| tool(n as f64 * spindle_hz) - 1.0)
                .collect(),
            dac: harmonics.map(|n| dac(n as f64 * spindle_hz)).collect(),
            forward: planner.plan_fft_forward(RING_SAMPLES),
            inverse: planner.plan_fft_inverse(RING_SAMPLES),
        }
    }

    /// The harmonics of a ring's [`RING_SAMPLES`] heights (unnormalised DFT).
    fn spectrum(&self, ring: &[f64]) -> Vec<C> {
        let mut input = ring.to_vec();
        let mut x = self.forward.make_output_vec();
        // Lengths match the plan by construction.
        let _ = self.forward.process(&mut input, &mut x);
        x
    }

    /// The waveform whose harmonics are `x` weighted by `w(n)`.
    fn waveform(&self, x: &[C], w: impl Fn(usize) -> C) -> Vec<f64> {
        let half = RING_SAMPLES / 2;
        let mut spec: Vec<C> = x.iter().enumerate().map(|(n, v)| v * w(n)).collect();
        spec[0].im = 0.0;
        spec[half].im = 0.0;
        let mut out = vec![0.0; RING_SAMPLES];
        // A spectrum with real ends never fails to invert.
        let _ = self.inverse.process(&mut spec, &mut out);
        out.iter_mut().for_each(|v| *v /= RING_SAMPLES as f64);
        out
    }

    /// The predicted tool error (tool − path, m) at each of the ring's samples, at steady
    /// state.
    pub fn predicted_error(&self, ring: &[f64]) -> Vec<f64> {
        let x = self.spectrum(ring);
        self.waveform(&x, |n| self.tool_error[n])
    }
}

/// The largest |value| (NaN if any is NaN).
fn peak(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, x| worst(a, x.abs()))
}

/// The larger of `a` and `b`, NaN if either is NaN (a band's worst case must not hide a NaN).
fn worst(a: f64, b: f64) -> f64 {
    if a.is_nan() || b.is_nan() {
        f64::NAN
    } else {
        a.max(b)
    }
}

/// A ring's samples of the FTS path and its contacts' worst tightness.
fn ring(path: &ToolPath, r: f64) -> (Vec<f64>, f64) {
    let mut tight = f64::NEG_INFINITY;
    let heights = (0..RING_SAMPLES)
        .map(|k| {
            let theta = k as f64 * TAU / RING_SAMPLES as f64;
            let (contact, fts) = path.fts_at(r, theta);
            tight = match contact {
                Some(c) => tight.max(path.tightness(&c, theta)),
                None => f64::INFINITY,
            };
            fts
        })
        .collect();
    (heights, tight)
}

/// The machining, tool path and clearance angle (rad) of `plan`, or an error naming
/// `scenario.surface.kind` when it does not cut a prescription.
pub fn prescription_of(plan: &Plan) -> Result<(&Machining, &ToolPath, f64), RunError> {
    let not_a_prescription = || {
        RunError::from(plan.origin.invalid(
            "scenario.surface.kind",
            "(not a prescription)",
            "\"prescription\" for a tool path",
        ))
    };
    match (&plan.config.scenario, &plan.surface) {
        (Scenario::Machine(m), Some(LoadedSurface::Prescription(path))) => match m.surface {
            SurfaceConfig::Prescription {
                clearance_angle_rad,
                ..
            } => Ok((m, path, clearance_angle_rad)),
            _ => Err(not_a_prescription()),
        },
        _ => Err(not_a_prescription()),
    }
}

/// The demands of `plan`'s prescription over `bands` radius bands from its aperture's edge
/// to the axis; an error when the plan does not cut a prescription.
pub fn feasibility(plan: &Plan, bands: usize) -> Result<Feasibility, RunError> {
    let (m, path, clearance) = prescription_of(plan)?;
    let omega = m.rad_per_s();
    let spindle_hz = omega / TAU;
    let half = RING_SAMPLES / 2;
    let ring_loop = RingLoop::new(plan, spindle_hz);
    let aperture = path.prescription().aperture_radius_m;
    let mut out_bands = Vec::with_capacity(bands);
    for b in 0..bands {
        let outer = aperture * (1.0 - b as f64 / bands as f64);
        let inner = aperture * (1.0 - (b + 1) as f64 / bands as f64);
        let mut band = Band {
            radius_m: [inner, outer],
            stroke_m: 0.0,
            peak_height_m: 0.0,
            peak_velocity_m_per_s: 0.0,
            peak_acceleration_m_per_s2: 0.0,
            peak_voltage_v: 0.0,
            bandwidth_hz: 0.0,
            predicted_rms_m: 0.0,
            slope_along_cut_rad: 0.0,
            nose_tightness: f64::NEG_INFINITY,
        };
        for i in 0..RINGS_PER_BAND {
            let r = outer - (outer - inner) * i as f64 / RINGS_PER_BAND as f64;
            if r <= 0.0 {
                continue;
            }
            let (heights, tight) = ring(path, r);
            let (lo, hi) = heights
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                    (a.min(v), b.max(v))
                });
            let x = ring_loop.spectrum(&heights);
            let jn = |n: usize| C::new(0.0, n as f64);
            let slope = peak(&ring_loop.waveform(&x, jn));
            band.stroke_m = worst(band.stroke_m, hi - lo);
            band.peak_height_m = worst(band.peak_height_m, hi.abs().max(lo.abs()));
            band.peak_velocity_m_per_s = worst(band.peak_velocity_m_per_s, omega * slope);
            band.peak_acceleration_m_per_s2 = worst(
                band.peak_acceleration_m_per_s2,
                omega * omega * peak(&ring_loop.waveform(&x, |n| C::new(-((n * n) as f64), 0.0))),
            );
            band.peak_voltage_v = worst(
                band.peak_voltage_v,
                peak(&ring_loop.waveform(&x, |n| ring_loop.dac[n])),
            );
            band.slope_along_cut_rad = worst(band.slope_along_cut_rad, libm::atan(slope / r));
            band.nose_tightness = worst(band.nose_tightness, tight);
            // Mean square of each harmonic (n ≥ 1): 2|Xₙ|²/N² (the Nyquist bin once).
            let power = |n: usize, v: C| {
                let k = if n == half { 1.0 } else { 2.0 };
                k * v.norm_sqr() / (RING_SAMPLES * RING_SAMPLES) as f64
            };
            let total: f64 = (1..=half).map(|n| power(n, x[n])).sum();
            let mut acc = 0.0;
            let mut top = 0;
            for (n, &v) in x.iter().enumerate().take(half + 1).skip(1) {
                acc += power(n, v);
                top = n;
                if acc >= 0.999 * total {
                    break;
                }
            }
            band.bandwidth_hz = worst(band.bandwidth_hz, top as f64 * spindle_hz);
            let error: f64 = (1..=half)
                .map(|n| power(n, x[n] * ring_loop.tool_error[n]))
                .sum();
            band.predicted_rms_m = worst(band.predicted_rms_m, error.sqrt());
        }
        out_bands.push(band);
    }
    let symmetric: Vec<f64> = (0..=64)
        .map(|i| path.symmetric_m(aperture * i as f64 / 64.0))
        .collect();
    let dac_range = plan.config.plant.dac.range_v;
    let mut f = Feasibility {
        spindle_rpm: m.spindle_rpm,
        nose_radius_m: path.nose_radius_m(),
        z_slide_travel_m: symmetric.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - symmetric.iter().cloned().fold(f64::INFINITY, f64::min),
        // The bands sample every ring at RING_SAMPLES angles (finer than the path's own table).
        fts_stroke_m: out_bands
            .iter()
            .fold(path.fts_range_m().1 - path.fts_range_m().0, |a, b| {
                a.max(b.stroke_m)
            }),
        nyquist_hz: plan.config.plant.timing.servo_rate_hz / 2.0,
        bands: out_bands,
        dac_range_v: dac_range,
        measurable_m: (plan.config.plant.adc.range_v / plan.config.plant.capa.sensitivity_v_per_m)
            .min(
                plan.config
                    .protection
                    .position_limit_m
                    .unwrap_or(f64::INFINITY),
            ),
        start_height_m: path.fts_m(m.start_radius_m, 0.0),
        following_error_limit_m: if plan.config.protection.enabled {
            plan.config.protection.following_error_m
        } else {
            0.0
        },
        clearance_angle_rad: clearance,
        exceeded: Vec::new(),
    };
    f.exceeded = exceeded(&f);
    Ok(f)
}

/// The limits each band exceeds, in words.
fn exceeded(f: &Feasibility) -> Vec<String> {
    let mm = |r: [f64; 2]| format!("{:.2}–{:.2} mm", r[0] * 1e3, r[1] * 1e3);
    let mut out = Vec::new();
    if f.following_error_limit_m > 0.0 && f.start_height_m.abs() > f.following_error_limit_m {
        out.push(format!(
            "the cut starts {:.2} µm from the flexure's rest, beyond the {:.1} µm following-error trip (protection.following_error_m): the first tick would trip",
            f.start_height_m * 1e6,
            f.following_error_limit_m * 1e6
        ));
    }
    for b in &f.bands {
        let values = [
            b.stroke_m,
            b.peak_velocity_m_per_s,
            b.peak_acceleration_m_per_s2,
            b.peak_voltage_v,
            b.predicted_rms_m,
            b.slope_along_cut_rad,
        ];
        if values.iter().any(|v| !v.is_finite()) {
            out.push(format!(
                "{}: the path or the loop's response is not a number there (a surface undefined in the band, or a loop the model cannot evaluate)",
                mm(b.radius_m)
            ));
        }
        if b.bandwidth_hz > f.nyquist_hz {
            out.push(format!(
                "{}: the path moves at up to {:.0} Hz, beyond the servo's Nyquist frequency {:.0} Hz (plant.timing.servo_rate_hz): slow the spindle",
                mm(b.radius_m), b.bandwidth_hz, f.nyquist_hz
            ));
        }
        if b.peak_height_m > f.measurable_m {
            out.push(format!(
                "{}: the FTS must reach ±{:.2} µm, beyond the ±{:.2} µm the gap sensor reads (plant.adc.range_v / plant.capa.sensitivity_v_per_m, protection.position_limit_m)",
                mm(b.radius_m), b.peak_height_m * 1e6, f.measurable_m * 1e6
            ));
        }
        if b.peak_voltage_v > f.dac_range_v {
            out.push(format!(
                "{}: the loop would command {:.2} V, beyond the DAC's ±{} V (plant.dac.range_v): slow the spindle",
                mm(b.radius_m), b.peak_voltage_v, f.dac_range_v
            ));
        }
        if b.slope_along_cut_rad > f.clearance_angle_rad {
            out.push(format!(
                "{}: the surface rises {:.1}° along the cut, steeper than the tool's {:.1}° clearance (scenario.surface.clearance_angle_rad): the flank would rub",
                mm(b.radius_m), b.slope_along_cut_rad.to_degrees(), f.clearance_angle_rad.to_degrees()
            ));
        }
        if b.nose_tightness >= 1.0 {
            out.push(format!(
                "{}: a concave region tighter than the nose (R·κ = {:.2}; scenario.tool_nose_radius_m)",
                mm(b.radius_m), b.nose_tightness
            ));
        }
    }
    out
}

/// The command tables for a machine's own controller: `rings` radii from the aperture's edge
/// to the axis (rows), each with the Z slide's height there (`z_slide_m`), then the FTS height
/// at `counts` equally spaced encoder counts of a revolution (columns); heights in m toward
/// the tool, the tool's tip at the sum. CSV with a header naming the counts.
pub fn command_table(path: &ToolPath, rings: usize, counts: usize, pulses_per_rev: u64) -> String {
    use std::fmt::Write as _;
    let aperture = path.prescription().aperture_radius_m;
    let step = pulses_per_rev as f64 / counts as f64;
    let mut s = String::from("radius_m,z_slide_m");
    for k in 0..counts {
        let _ = write!(s, ",count_{}", (k as f64 * step).round() as u64);
    }
    s.push('\n');
    for i in 0..rings {
        let r = aperture * (1.0 - i as f64 / (rings - 1).max(1) as f64);
        let _ = write!(s, "{r:.9e},{:.9e}", path.symmetric_m(r));
        for k in 0..counts {
            let theta = TAU * (k as f64 * step).round() / pulses_per_rev as f64;
            let _ = write!(s, ",{:.6e}", path.fts_m(r, theta));
        }
        s.push('\n');
    }
    s
}
