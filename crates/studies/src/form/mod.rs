//! What the white-light interferometer would show after a machining run (thesis §8.5): the
//! form error (true tool position minus design surface, where the tool was) as statistics and
//! as a map over the machined band, the machined amplitude of a sinusoidal grid (Fig 8-23's
//! peak-to-valley), the surface roughness with its feed marks (§8.5.1), and a segment of
//! commanded vs true tool trajectory (Figs 8-15, 8-20).

pub mod roughness;

use crate::error::StudyError;
use nalgebra::{SMatrix, SVector};
use recorder::Frame;
use roughness::{Roughness, RoughnessWindow};
use run_config::surface::LoadedSurface;
use run_config::workpiece::{SpindleMotion, SpiralCut};
use run_config::{Machining, RunConfig, Scenario};
use runner::plan::{PRESCRIPTION_INPUT, SURFACE_INPUT};
use runner::recording::{FrameSink, RunHeader};
use runner::run::{run_with, RunOptions};
use runner::summary::{Acc, Stats, Summary};
use runner::Plan;
use runner::RunError;
use serde::Serialize;
use servo_core::surface::SinusoidalGrid;
use std::f64::consts::TAU;

/// Angular bins of the form-error map per revolution (0.1°).
pub const MAP_COLUMNS: usize = 3600;

/// Length of the recorded trajectory segment in s.
pub const SEGMENT_S: f64 = 0.02;

/// The machined amplitude of a sinusoidal grid (least-squares fit of the true tool position
/// to the grid's sine and cosine terms over the band, so phase lag does not count).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct GridAmplitude {
    /// Designed peak-to-valley along X, `2·Ax`, in m (Table 8-5: 10 µm).
    pub nominal_pv_x_m: f64,
    /// Machined peak-to-valley along X in m (thesis, edge, no feedforward: 11.18 µm).
    pub machined_pv_x_m: f64,
    /// Designed peak-to-valley along Y in m.
    pub nominal_pv_y_m: f64,
    /// Machined peak-to-valley along Y in m.
    pub machined_pv_y_m: f64,
}

/// The result of a machining run.
#[derive(Debug, Clone, Serialize)]
pub struct FormReport {
    /// Innermost and outermost radius of the evaluated band in m.
    pub band_m: [f64; 2],
    /// Spindle revolutions evaluated.
    pub revolutions: f64,
    /// Highest tool-motion frequency of the X term in the band, `r·ω/λx`, in Hz (grids).
    pub max_motion_frequency_hz: Option<f64>,
    /// Form error `tool − design` in m over the band; `rms` with the mean (piston: the tool
    /// shank's static compression under a constant cutting force) removed, as a form
    /// measurement reports it.
    pub form_error_m: Stats,
    /// Largest |form error − mean| in m (the transition overshoot of §8.5.3).
    pub max_abs_form_error_m: f64,
    /// Following error `reference − measured` in m (what the capacitive sensor shows).
    pub following_error_m: Stats,
    /// Machined amplitude, for a sinusoidal grid.
    pub grid: Option<GridAmplitude>,
    /// Roughness over a measurement area in the middle of the band (None: band too narrow).
    pub roughness: Option<Roughness>,
    /// Largest cutting force in N.
    pub max_cutting_force_n: f64,
    /// Form error RMS of each revolution in m (the run's mean removed), the first (outermost)
    /// first: how a repetitive controller converges.
    pub revolution_rms_m: Vec<f64>,
    /// Lowest and highest form error of each revolution in m, the first (outermost) first: the
    /// PV of any run of revolutions is the highest of their highs less the lowest of their lows.
    pub revolution_range_m: Vec<[f64; 2]>,
    /// RMS in m of the spindle-synchronous part of the form error: the error at each angle
    /// averaged over the complete revolutions, the run's mean removed (None: no complete
    /// revolution).
    pub synchronous_rms_m: Option<f64>,
}

/// One row of the trajectory segment.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct SegmentRow {
    /// Time in s.
    pub time_s: f64,
    /// Commanded (design) height in m.
    pub reference_m: f64,
    /// True tool position in m.
    pub tool_m: f64,
    /// Measured position in m.
    pub measured_m: f64,
    /// Cutting force in N.
    pub cutting_force_n: f64,
}

/// Accumulates a [`FormReport`], the form-error map and the segment, frame by frame.
pub struct FormAnalysis {
    cut: SpiralCut,
    grid: Option<SinusoidalGrid>,
    /// The configured speed in rad/s (the segment's window and the motion frequency).
    rad_per_s: f64,
    /// The machine's tool centre height and X offset, m.
    tool_setting_m: [f64; 2],
    /// The spindle's true angle over time (with its drift and step).
    spindle: SpindleMotion,
    settle_s: f64,
    form: Acc,
    range: (f64, f64),
    following: Acc,
    max_force: f64,
    first_theta: Option<f64>,
    last_theta: f64,
    rows: usize,
    map_sum: Vec<f64>,
    map_count: Vec<u32>,
    /// Per revolution: Σe, Σe², samples.
    revolution_sums: Vec<(f64, f64, u64)>,
    /// Lowest and highest form error per revolution, m.
    revolution_range: Vec<[f64; 2]>,
    fit_ata: SMatrix<f64, 5, 5>,
    fit_atb: SVector<f64, 5>,
    segment_from: Option<f64>,
    segment: Vec<SegmentRow>,
    roughness: Option<RoughnessWindow>,
}

impl FormAnalysis {
    /// The analysis of a run of `c` cutting `surface` as `m` says.
    pub fn new(c: &RunConfig, m: &Machining, surface: LoadedSurface) -> Self {
        let spindle = SpindleMotion::of(m);
        let revolutions = spindle.angle_rad(c.run.duration_s) / TAU;
        let rows = ((revolutions - 1e-9).ceil() as usize).max(1);
        let spiral = m.spiral();
        let theta = |t: f64| spindle.angle_rad(t);
        let outer = spiral.radius_m(theta(c.run.settle()));
        let roughness = RoughnessWindow::new(
            spiral,
            (spiral.radius_m(theta(c.run.duration_s)), outer),
            m.tool_nose_radius_m,
            outer * m.rad_per_s() / c.plant.timing.servo_rate_hz,
        );
        FormAnalysis {
            roughness,
            grid: match surface {
                LoadedSurface::Grid(g) => Some(g),
                _ => None,
            },
            cut: SpiralCut::new(m, surface),
            rad_per_s: m.rad_per_s(),
            tool_setting_m: m.tool_setting_m(&c.run),
            spindle,
            settle_s: c.run.settle(),
            form: Acc::default(),
            range: (f64::INFINITY, f64::NEG_INFINITY),
            following: Acc::default(),
            max_force: 0.0,
            first_theta: None,
            last_theta: 0.0,
            rows,
            map_sum: vec![0.0; rows * MAP_COLUMNS],
            map_count: vec![0; rows * MAP_COLUMNS],
            revolution_sums: vec![(0.0, 0.0, 0); rows],
            revolution_range: vec![[f64::INFINITY, f64::NEG_INFINITY]; rows],
            fit_ata: SMatrix::zeros(),
            fit_atb: SVector::zeros(),
            segment_from: None,
            segment: Vec::new(),
        }
    }

    /// Adds one recorded frame (the tool position at the frame's time).
    pub fn add(&mut self, f: &Frame) {
        let t = f.time_ns as f64 * 1e-9;
        if t < self.settle_s {
            return;
        }
        let theta = self.spindle.angle_rad(t);
        let design = self.cut.height_m(theta);
        let tool = f.truth.tool_m as f64;
        // Against the design, not a compensated path (a prescription's [compensation]); where
        // the tool's setting put it (first order: the error of the point it was sent to).
        let e = tool - design
            + self.cut.compensation_m(theta)
            + self.cut.setting_error_m(theta, self.tool_setting_m);
        self.form.add(e);
        if let Some(w) = &mut self.roughness {
            w.add(theta, e);
        }
        self.range = (self.range.0.min(e), self.range.1.max(e));
        self.following.add(f.telemetry.following_error_m as f64);
        self.max_force = self.max_force.max(f.truth.cutting_force_n.abs() as f64);
        self.first_theta.get_or_insert(theta);
        self.last_theta = theta;
        let turns = theta / TAU;
        let row = (turns.floor() as usize).min(self.rows - 1);
        let col = ((turns.fract() * MAP_COLUMNS as f64) as usize).min(MAP_COLUMNS - 1);
        self.map_sum[row * MAP_COLUMNS + col] += e;
        self.map_count[row * MAP_COLUMNS + col] += 1;
        let sums = &mut self.revolution_sums[row];
        *sums = (sums.0 + e, sums.1 + e * e, sums.2 + 1);
        let range = &mut self.revolution_range[row];
        *range = [range[0].min(e), range[1].max(e)];
        if let Some(g) = &self.grid {
            let r = self.cut.radius_m(theta);
            let (x, y) = (r * libm::cos(theta), r * libm::sin(theta));
            let (px, py) = (TAU * x / g.lambda_x_m, TAU * y / g.lambda_y_m);
            let a = SVector::<f64, 5>::from([
                libm::sin(px),
                libm::cos(px),
                libm::sin(py),
                libm::cos(py),
                1.0,
            ]);
            self.fit_ata += a * a.transpose();
            self.fit_atb += a * tool;
        }
        // The segment: from the first quarter turn after settling (fastest X motion there).
        let from = *self.segment_from.get_or_insert_with(|| {
            let quarter = (turns - 0.25).ceil() + 0.25;
            quarter * TAU / self.rad_per_s - SEGMENT_S / 2.0
        });
        if t >= from && t < from + SEGMENT_S {
            self.segment.push(SegmentRow {
                time_s: t,
                reference_m: f.telemetry.reference_m as f64,
                tool_m: tool,
                measured_m: f.telemetry.measured_m as f64,
                cutting_force_n: f.truth.cutting_force_n as f64,
            });
        }
    }

    /// The report.
    pub fn report(&self) -> FormReport {
        let (first, last) = (self.first_theta.unwrap_or(0.0), self.last_theta);
        let outer = self.cut.radius_m(first);
        let grid = self.grid.and_then(|g| {
            self.fit_ata.try_inverse().map(|inv| {
                let c = inv * self.fit_atb;
                GridAmplitude {
                    nominal_pv_x_m: 2.0 * g.ax_m.abs(),
                    machined_pv_x_m: 2.0 * libm::hypot(c[0], c[1]),
                    nominal_pv_y_m: 2.0 * g.ay_m.abs(),
                    machined_pv_y_m: 2.0 * libm::hypot(c[2], c[3]),
                }
            })
        });
        let form = self.form.stats();
        FormReport {
            band_m: [self.cut.radius_m(last), outer],
            revolutions: (last - first) / TAU,
            max_motion_frequency_hz: self.grid.map(|g| outer * self.rad_per_s / g.lambda_x_m),
            form_error_m: Stats {
                rms: (form.rms * form.rms - form.mean * form.mean)
                    .max(0.0)
                    .sqrt(),
                ..form
            },
            max_abs_form_error_m: (self.range.1 - form.mean)
                .max(form.mean - self.range.0)
                .max(0.0),
            following_error_m: self.following.stats(),
            grid,
            roughness: self.roughness.as_ref().and_then(RoughnessWindow::roughness),
            max_cutting_force_n: self.max_force,
            revolution_rms_m: self
                .revolution_sums
                .iter()
                .filter(|s| s.2 > 0)
                .map(|&(sum, sq, n)| {
                    let n = n as f64;
                    let mu = form.mean;
                    (sq / n - 2.0 * mu * sum / n + mu * mu).max(0.0).sqrt()
                })
                .collect(),
            revolution_range_m: self
                .revolution_sums
                .iter()
                .zip(&self.revolution_range)
                .filter(|(s, _)| s.2 > 0)
                .map(|(_, &range)| range)
                .collect(),
            synchronous_rms_m: self.synchronous_rms(form.mean),
        }
    }

    /// See [`FormReport::synchronous_rms_m`].
    fn synchronous_rms(&self, mean: f64) -> Option<f64> {
        let complete: Vec<usize> = (0..self.rows)
            .filter(|&r| {
                self.map_count[r * MAP_COLUMNS..(r + 1) * MAP_COLUMNS]
                    .iter()
                    .all(|&n| n > 0)
            })
            .collect();
        if complete.is_empty() {
            return None;
        }
        let mut sq = 0.0;
        for col in 0..MAP_COLUMNS {
            let at = |r: usize| {
                let i = r * MAP_COLUMNS + col;
                self.map_sum[i] / f64::from(self.map_count[i])
            };
            let average = complete.iter().map(|&r| at(r)).sum::<f64>() / complete.len() as f64;
            sq += (average - mean) * (average - mean);
        }
        Some((sq / MAP_COLUMNS as f64).sqrt())
    }

    /// The form-error map: mean error per 0.1° bin and revolution (m; NaN where the run did
    /// not pass), row 0 the first (outermost) revolution.
    pub fn map(&self) -> (usize, Vec<f64>) {
        let values = self
            .map_sum
            .iter()
            .zip(&self.map_count)
            .map(|(&s, &n)| if n > 0 { s / n as f64 } else { f64::NAN })
            .collect();
        (self.rows, values)
    }

    /// A radial profile of the machined face across ten feed marks (see
    /// [`RoughnessWindow::radial_profile`]); None when the band is too narrow.
    pub fn roughness_profile(&self) -> Option<Vec<[f64; 4]>> {
        self.roughness.as_ref()?.radial_profile(10)
    }

    /// The recorded trajectory segment.
    pub fn segment(&self) -> &[SegmentRow] {
        &self.segment
    }
}

/// Runs the machining scenario of `plan` (recording as `opts` says) and analyses every frame.
pub fn run_machining(
    plan: &Plan,
    opts: RunOptions<'_>,
) -> Result<(Summary, FormAnalysis), StudyError> {
    let (Scenario::Machine(m), Some(surface)) = (&plan.config.scenario, &plan.surface) else {
        return Err(plan
            .origin
            .invalid(
                "scenario.kind",
                "(not machine)",
                "\"machine\" for a machining run",
            )
            .into());
    };
    let mut analysis = FormAnalysis::new(&plan.config, m, surface.clone());
    let summary = run_with(plan, opts, |f| analysis.add(f))?;
    Ok((summary, analysis))
}

/// The form analysis of a machining recording, built from its header (configuration and the
/// embedded surface image) and fed in the same streaming pass as its summary; none for other
/// scenarios.
#[derive(Default)]
pub struct FormSink {
    /// The analysis, once the header named a machining scenario.
    pub analysis: Option<FormAnalysis>,
}

impl FrameSink for FormSink {
    fn header(&mut self, h: &RunHeader) -> Result<(), RunError> {
        if let Scenario::Machine(m) = &h.loaded.config.scenario {
            let file = [SURFACE_INPUT, PRESCRIPTION_INPUT]
                .iter()
                .find_map(|name| h.inputs.get(*name))
                .map(Vec::as_slice);
            let surface = LoadedSurface::load(m, &h.loaded.origin, file)?;
            self.analysis = Some(FormAnalysis::new(&h.loaded.config, m, surface));
        }
        Ok(())
    }

    fn frame(&mut self, f: &Frame) {
        if let Some(a) = &mut self.analysis {
            a.add(f);
        }
    }
}
