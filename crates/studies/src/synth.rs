//! H2-optimal controller design on the simulator's exact discrete model (thesis Ch. 6, in the
//! spirit of Fig 6-3 but with the plant the simulator runs): the noise shaping filters are
//! already in the model, so the controller directly minimises the variance of the **true** tool
//! position (z1, in nm) plus `ρ²·u²` (z2), given the sensor, current, base and converter noise.
//! The transport delay, the hold and the ADC averaging are in the tick, so the design knows
//! them (DESIGN.md, "Discrete controllers are designed knowing this delay").

use crate::budget::Budget;
use crate::error::StudyError;
use design::h2::{h2syn_discrete, GeneralizedPlant};
use lti::StateSpace;
use nalgebra::DMatrix;
use plant_sim::sampled_noise::SampledNoise;
use run_config::{ControllerConfig, ControllerKind, MadeFor, Origin};
use runner::Plan;
use servo_config::{Stability, MAX_SS_ORDER};

/// The designed controller in the form `servo run --controller ss` loads (input: position
/// error `r − gap` in sensor volts, output: command in V) and what the design predicts.
#[derive(Debug, Clone)]
pub struct Design {
    /// The controller, sampled at `sample_rate_hz`.
    pub controller: StateSpace,
    /// Its sample rate in Hz (the run's servo rate).
    pub sample_rate_hz: f64,
    /// Closed-loop H2 norm of the design problem (nm and weighted V, per-sample white inputs).
    pub h2_norm: f64,
    /// Closed-loop spectral radius of the design model.
    pub spectral_radius: f64,
    /// The plant and rate it was designed for (written into the controller file).
    pub made_for: MadeFor,
    /// The offline check of its loop on the plant (written into the controller file: a running
    /// loop that loads it keeps this gain range), once checked ([`synthesize`]).
    pub stability: Option<Stability>,
    /// What the design's Riccati equations warned of, each led by the key that set up that
    /// equation (`effort_weight` the control one, `sensor_noise_scale` the filter one).
    pub warnings: Vec<String>,
}

/// The warnings of an H2 synthesis, each led by the key behind its equation.
fn keyed(warnings: &[design::h2::Warning], filter_key: &str) -> Vec<String> {
    warnings
        .iter()
        .map(|w| {
            let key = match w.equation {
                "control" => "effort_weight",
                _ => filter_key,
            };
            format!("{key}: {w}")
        })
        .collect()
}

impl Design {
    /// The controller file (TOML) for `servo run --controller ss --ss-file`.
    pub fn to_toml(&self) -> String {
        let rows = |m: &DMatrix<f64>| {
            let r: Vec<String> = (0..m.nrows())
                .map(|i| {
                    format!(
                        "[{}]",
                        (0..m.ncols())
                            .map(|j| format!("{:e}", m[(i, j)]))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )
                })
                .collect();
            format!("[\n  {},\n]", r.join(",\n  "))
        };
        let k = &self.controller;
        format!(
            "# H2-optimal controller designed by `servo synth h2` on the simulator's exact model.\n\
             # x⁺ = A x + B e, u = C x + D e; e = reference − measurement in sensor volts, u in V.\n\
             # {} states; design closed-loop H2 norm {:.6e}, spectral radius {:.6}.\n\
             sample_rate_hz = {}\na = {}\nb = {}\nc = {}\nd = {}\n\n{}{}",
            k.nx(),
            self.h2_norm,
            self.spectral_radius,
            self.sample_rate_hz,
            rows(&k.a),
            rows(&k.b),
            rows(&k.c),
            rows(&k.d),
            self.made_for.to_toml("made_for"),
            self.stability.map_or(String::new(), |s| format!(
                "\n{}",
                servo_config::stability_toml("stability", &s)
            ))
        )
    }
}

impl Design {
    /// The same controller reduced to `order` states by balanced truncation (thesis Table 6-1
    /// sizes: 8, 13, full); returns the Hankel singular values and the H∞ error bound too.
    /// The controller itself must be stable.
    pub fn reduced(&self, order: usize) -> Result<(Design, Vec<f64>, f64), StudyError> {
        let r = lti::reduce::balanced_truncation(&self.controller, order)
            .map_err(StudyError::Reduction)?;
        let mut d = self.clone();
        d.controller = r.sys;
        Ok((d, r.hankel, r.error_bound))
    }
}

/// Designs the H2 controller for the plant of `plan` at its servo rate; `effort_nm_per_v` is ρ,
/// the weight of one volt of command against one nanometre of tool error.
pub fn h2_design(plan: &Plan, effort_nm_per_v: f64) -> Result<Design, StudyError> {
    h2_design_with(plan, effort_nm_per_v, 1.0)
}

/// [`h2_design`] assuming `sensor_noise_scale` times the plant's sensor noise (RMS): below 1
/// the design trusts the sensor more and closes a faster loop, above 1 a slower one — the knob
/// that brings an H2 design to a required bandwidth (1: the H2-optimal design).
pub fn h2_design_with(
    plan: &Plan,
    effort_nm_per_v: f64,
    sensor_noise_scale: f64,
) -> Result<Design, StudyError> {
    let c = &plan.config;
    let t = plan
        .sim
        .linear_tick()
        .ok_or(StudyError::NeedsLinearPlant { what: "H2 design" })?;
    let n = t.phi.nrows();
    // State [x, u[k−1], gap reading, sensor-noise state, quantisation state].
    let (iu, iy, is) = (n, n + 1, n + 2);
    let states = |s: &Option<SampledNoise>| s.as_ref().map_or(0, SampledNoise::states);
    let iq = is + states(&t.sensor_noise);
    let size = iq + states(&t.gap_quantisation);
    let sigma_w = t.white_variance.map(f64::sqrt);
    let sigma_s = t
        .sensor_noise
        .as_ref()
        .map_or(0.0, |s| s.variance.sqrt() * sensor_noise_scale);
    // Measurement noise on the reading: the ADC's rounding error, coloured as the budget has
    // it (a floor on its innovation keeps D21 full rank for an ideal converter).
    let sigma_q = t
        .gap_quantisation
        .as_ref()
        .map_or(0.0, |q| q.variance.sqrt())
        .max(1e-3 * sigma_s)
        .max(1e-12);
    // w = [sensor innovation, current, base, accelerometer, quantisation innovation], unit
    // variance.
    let nw = 5;
    let mut a = DMatrix::zeros(size, size);
    let mut b1 = DMatrix::zeros(size, nw);
    let mut b2 = DMatrix::zeros(size, 1);
    a.view_mut((0, 0), (n, n)).copy_from(&t.phi);
    a.view_mut((0, iu), (n, 1)).copy_from(&t.g.column(0));
    b2.view_mut((0, 0), (n, 1)).copy_from(&t.g.column(1));
    b2[(iu, 0)] = 1.0;
    a.view_mut((iy, 0), (1, n)).copy_from(&t.y_x.row(0));
    a[(iy, iu)] = t.y_in[(0, 0)];
    b2[(iy, 0)] = t.y_in[(0, 1)];
    if let Some(sn) = &t.sensor_noise {
        sn.place(&mut a, &mut b1, (iy, is, 0), sigma_s);
    }
    for k in 0..3 {
        // plant input columns 3..6 are the current, base and accelerometer white inputs
        b1.view_mut((0, 1 + k), (n, 1))
            .copy_from(&(t.g.column(3 + k) * sigma_w[k]));
        b1[(iy, 1 + k)] = t.y_in[(0, 3 + k)] * sigma_w[k];
    }
    let mut c1 = DMatrix::zeros(2, size);
    c1.view_mut((0, 0), (1, n))
        .copy_from(&(t.t_start.row(0) * 1e9));
    let d12 = DMatrix::from_column_slice(2, 1, &[0.0, effort_nm_per_v]);
    // The controller reads the stored reading plus its rounding error, c_q ξ + σ_q e now.
    let mut c2 = DMatrix::zeros(1, size);
    c2[(0, iy)] = 1.0;
    let mut d21 = DMatrix::zeros(1, nw);
    d21[(0, 4)] = sigma_q;
    if let Some(q) = &t.gap_quantisation {
        let m = q.states();
        c2.view_mut((0, iq), (1, m)).copy_from(&q.sys.c);
        a.view_mut((iq, iq), (m, m)).copy_from(&q.sys.a);
        b1.view_mut((iq, 4), (m, 1))
            .copy_from(&(&q.sys.b * sigma_q));
    }
    let plant = GeneralizedPlant {
        a,
        b1,
        b2,
        c1,
        c2,
        d12,
        d21,
    };
    let k = h2syn_discrete(&plant)?;
    // The runner feeds e = r − gap: with r = 0, e = −gap, so negate the input side.
    let controller = StateSpace {
        a: k.k.a.clone(),
        b: -&k.k.b,
        c: k.k.c.clone(),
        d: -&k.k.d,
    };
    Ok(Design {
        controller,
        sample_rate_hz: c.plant.timing.servo_rate_hz,
        h2_norm: k.h2_norm,
        spectral_radius: k.spectral_radius,
        made_for: run_config::made_for_plant(&plan.config.plant),
        stability: None,
        warnings: keyed(&k.warnings, "sensor_noise_scale"),
    })
}

/// What `servo synth h2` (and `fts_servo.synth_h2`) is asked for.
#[derive(Debug, Clone, Copy)]
pub struct SynthRequest {
    /// The design problem.
    pub weights: SynthWeights,
    /// Reduce the controller to this many states by balanced truncation (None: full order).
    pub order: Option<usize>,
}

/// The H2 design problem.
#[derive(Debug, Clone, Copy)]
pub enum SynthWeights {
    /// The simulator's exact discrete model and noise ([`h2_design_with`]).
    Exact {
        /// ρ, nm of tool error per V of command.
        effort_weight: f64,
        /// Scale of the sensor noise the design assumes (1: the plant's).
        sensor_noise_scale: f64,
    },
    /// §6.3's weighting filters ([`thesis_design`]).
    Thesis {
        /// ρ on the We/Wu problem.
        effort_weight: f64,
    },
}

/// A synthesised controller, checked in the loop it closes: what `servo synth h2` writes and
/// prints and `fts_servo.synth_h2` returns.
#[derive(Clone)]
pub struct Synthesis {
    /// The controller (reduced when asked), with its loop's offline check.
    pub design: Design,
    /// States before reduction, the Hankel singular values and the H∞ error bound of the
    /// controller (when reduced).
    pub reduction: Option<(usize, Vec<f64>, f64)>,
    /// The run of `plan` with this controller.
    pub plan: Plan,
    /// What the loop it closes is predicted to do.
    pub prediction: SynthPrediction,
}

/// What a synthesised controller's loop is predicted to do.
#[derive(Debug, Clone, serde::Serialize)]
pub struct SynthPrediction {
    /// Controller states.
    pub states: usize,
    /// Its sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Spectral radius of the sampled closed loop.
    pub spectral_radius: f64,
    /// −3 dB closed-loop bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Predicted RMS following error, m.
    pub following_rms_m: f64,
    /// Predicted RMS true tool error, m.
    pub true_rms_m: f64,
    /// The output scales between which the loop is stable.
    pub stability: Stability,
    /// Margins of the loop broken at the DAC (None on a plant without a linear tick).
    pub margins: Option<design::loops::Margins>,
    /// What the design warned of ([`Design::warnings`]).
    pub warnings: Vec<String>,
}

/// Designs the H2 controller of `request` for `plan`, reduces it if asked, closes the loop
/// with it, checks that loop (its gain range goes into the controller file) and predicts its
/// budget. Errors name the request's keys (`order`, `sensor_noise_scale`, `effort_weight`).
pub fn synthesize(plan: &Plan, request: &SynthRequest) -> Result<Synthesis, StudyError> {
    let at = Origin::default();
    let mut design = match request.weights {
        SynthWeights::Exact {
            effort_weight,
            sensor_noise_scale,
        } => {
            if !(sensor_noise_scale > 0.0 && sensor_noise_scale.is_finite()) {
                return Err(at
                    .invalid(
                        "sensor_noise_scale",
                        sensor_noise_scale,
                        "> 0 (1: the plant's sensor noise)",
                    )
                    .into());
            }
            if !(effort_weight > 0.0 && effort_weight.is_finite()) {
                return Err(at
                    .invalid("effort_weight", effort_weight, "> 0 nm/V")
                    .into());
            }
            h2_design_with(plan, effort_weight, sensor_noise_scale)?
        }
        SynthWeights::Thesis { effort_weight } => {
            if !(effort_weight > 0.0 && effort_weight.is_finite()) {
                return Err(at.invalid("effort_weight", effort_weight, "> 0").into());
            }
            thesis_design(plan, &ThesisWeights::default(), effort_weight)?
        }
    };
    let full = design.controller.nx();
    let writable = full.min(MAX_SS_ORDER);
    let reduction = match request.order {
        Some(n) if !(1..=writable).contains(&n) => {
            return Err(at
                .invalid(
                    "order",
                    n,
                    &format!(
                        "1..={writable} states (the design has {full}; a controller file holds at most {MAX_SS_ORDER})"
                    ),
                )
                .into())
        }
        None if full > MAX_SS_ORDER => {
            return Err(at
                .invalid(
                    "order",
                    "none (full order)",
                    &format!(
                        "1..={MAX_SS_ORDER} states: the full-order design has {full}, more than a controller file holds"
                    ),
                )
                .into())
        }
        Some(n) => {
            let (reduced, hankel, bound) = design.reduced(n)?;
            design = reduced;
            Some((full, hankel, bound))
        }
        None => None,
    };
    // The loop it closes, from the file's own text (what a run reads back).
    let controller = ControllerConfig {
        kind: ControllerKind::Ss,
        ss_file: Some(runner::hot_swap::LOADED_FILE.into()),
        ..plan.config.controller.clone()
    };
    let with = plan.with_controller_file(controller, Some(design.to_toml().into_bytes()))?;
    let stability = runner::gain_range::gain_range(&with)?;
    design.stability = Some(stability);
    let b = Budget::new(&with.closed_loop, 400)?;
    let prediction = SynthPrediction {
        states: design.controller.nx(),
        sample_rate_hz: design.sample_rate_hz,
        spectral_radius: with.closed_loop.spectral_radius(),
        bandwidth_hz: b.bandwidth_hz,
        following_rms_m: b.following_rms_m,
        true_rms_m: b.true_rms_m,
        stability,
        margins: crate::margins::loop_margins(&with).ok(),
        warnings: design.warnings.clone(),
    };
    Ok(Synthesis {
        design,
        reduction,
        plan: with,
        prediction,
    })
}

/// `Ms` of thesis eq 6-4 for a closed loop of damping ratio `xi`:
/// `α = √(0.5 + 0.5√(1 + 8ξ²))`, `Ms = α√(α² + 4ξ²) / √((1 − α²)² + 4ξ²α²)`.
pub fn ms_for_damping(xi: f64) -> f64 {
    let alpha = (0.5 + 0.5 * (1.0 + 8.0 * xi * xi).sqrt()).sqrt();
    let a2 = alpha * alpha;
    alpha * (a2 + 4.0 * xi * xi).sqrt() / ((1.0 - a2).powi(2) + 4.0 * xi * xi * a2).sqrt()
}

/// The thesis §6.3 weights (Fig 6-3), SI units.
#[derive(Debug, Clone, Copy)]
pub struct ThesisWeights {
    /// We (eq 6-3) peak bound (eq 6-4 with ξ = 0.707: 1.2721).
    pub ms: f64,
    /// We corner ω_b in rad/s (thesis: 1, for zero static error).
    pub omega_b: f64,
    /// We ε (thesis: 1e-7, a near-integrator; 1 here — a pole at ω_b·ε = 1 rad/s — since a
    /// mode 5e-8 inside the unit circle per tick stalls the filter Riccati iteration).
    pub epsilon: f64,
    /// Wu (eq 6-5) M_u (thesis: 1e8).
    pub mu: f64,
    /// Wu ω_bu in rad/s (thesis: 1e8).
    pub omega_bu: f64,
    /// Wu ε₁ (not given in the thesis; 1e3 puts the Wu corner at 1e5 rad/s). Wu is used as
    /// ε₁·Wu so that ρ weighs a volt above the corner.
    pub epsilon1: f64,
    /// Cutting-force weight Wfc in N per unit white input.
    pub wfc_n: f64,
}

impl Default for ThesisWeights {
    fn default() -> Self {
        ThesisWeights {
            ms: ms_for_damping(0.707),
            omega_b: 1.0,
            epsilon: 1.0,
            mu: 1e8,
            omega_bu: 1e8,
            epsilon1: 1e3,
            wfc_n: 1e-3,
        }
    }
}

/// The thesis §6.3 design (Fig 6-3): plant-sim's continuous model (mechanics, current loop,
/// sensor, and the Wi, Wg noise filters it already contains), the sensor noise Ws at the
/// measurement, the cutting force through Wfc, the tool error (nm) weighted by We (eq 6-3) and
/// the command by ρ·ε₁·Wu (eq 6-5); discretised at the servo rate with the loop's transport
/// delay (exact switching inside the tick; the thesis designed in continuous time without it),
/// noise held per tick with the variance of white noise of one-sided PSD 1/Hz up to fs/2, and
/// solved by discrete H2 synthesis (SB10ED) in balanced coordinates.
pub fn thesis_design(plan: &Plan, w: &ThesisWeights, effort: f64) -> Result<Design, StudyError> {
    use plant_sim::model::{input, output, PlantModel};
    let c = &plan.config;
    let mut params = c.plant;
    params.actuator.model = plant_sim::params::CurrentLoopModel::Ideal;
    let g = PlantModel::new(&params)?.sys;
    let n = g.nx();
    let (iwe, iwu, size) = (n, n + 1, n + 2);
    let tool = g.c.row(output::TOOL_M) * 1e9;
    let sensor = g.c.row(output::SENSOR_V);
    let ws = c.plant.noise.sensor_v_per_rt_hz;
    let first_order =
        |num: &[f64], den: &[f64]| StateSpace::from_tf(num, den).map_err(StudyError::Model);
    // We = (s/Ms + ω_b)/(s + ω_b ε);  ε₁·Wu = ε₁(s + ω_bu/M_u)/(ε₁ s + ω_bu).
    let we = first_order(&[1.0 / w.ms, w.omega_b], &[1.0, w.omega_b * w.epsilon])?;
    let wu = first_order(
        &[w.epsilon1, w.epsilon1 * w.omega_bu / w.mu],
        &[w.epsilon1, w.omega_bu],
    )?;
    let nw = 4;
    let mut a = DMatrix::zeros(size, size);
    a.view_mut((0, 0), (n, n)).copy_from(&g.a);
    a.view_mut((iwe, 0), (1, n))
        .copy_from(&(&tool * we.b[(0, 0)]));
    a[(iwe, iwe)] = we.a[(0, 0)];
    a[(iwu, iwu)] = wu.a[(0, 0)];
    let mut b1 = DMatrix::zeros(size, nw);
    b1.view_mut((0, 0), (n, 1))
        .copy_from(&g.b.column(input::CURRENT_WHITE));
    b1.view_mut((0, 1), (n, 1))
        .copy_from(&g.b.column(input::BASE_WHITE));
    b1.view_mut((0, 3), (n, 1))
        .copy_from(&(g.b.column(input::CUTTING_FORCE_N) * w.wfc_n));
    let mut b2 = DMatrix::zeros(size, 1);
    b2.view_mut((0, 0), (n, 1))
        .copy_from(&g.b.column(input::COMMAND_V));
    b2[(iwu, 0)] = wu.b[(0, 0)];
    let mut c1 = DMatrix::zeros(2, size);
    c1.view_mut((0, 0), (1, n))
        .copy_from(&(&tool * we.d[(0, 0)]));
    c1[(0, iwe)] = we.c[(0, 0)];
    c1[(1, iwu)] = effort * wu.c[(0, 0)];
    let d12 = DMatrix::from_column_slice(2, 1, &[0.0, effort * wu.d[(0, 0)]]);
    let mut c2 = DMatrix::zeros(1, size);
    c2.view_mut((0, 0), (1, n)).copy_from(&(-sensor));
    let mut d21 = DMatrix::zeros(1, nw);
    d21[(0, 2)] = -ws;
    let period = c.plant.period_s();
    let fs = c.plant.timing.servo_rate_hz;
    let delayed = lti::DelayedZoh::new(&a, &b2, period, c.plant.timing.delay_s)?;
    let (_, gw) = lti::zoh(&a, &b1, period);
    let sigma = (fs / 2.0).sqrt();
    let m = size + 1;
    let mut ad = DMatrix::zeros(m, m);
    ad.view_mut((0, 0), (size, size)).copy_from(&delayed.phi);
    ad.view_mut((0, size), (size, 1))
        .copy_from(&delayed.gamma_prev);
    let mut b2d = DMatrix::zeros(m, 1);
    b2d.view_mut((0, 0), (size, 1))
        .copy_from(&delayed.gamma_now);
    b2d[(size, 0)] = 1.0;
    let mut b1d = DMatrix::zeros(m, nw);
    b1d.view_mut((0, 0), (size, nw)).copy_from(&(gw * sigma));
    let widen = |c: &DMatrix<f64>| {
        let mut w = DMatrix::zeros(c.nrows(), m);
        w.view_mut((0, 0), (c.nrows(), size)).copy_from(c);
        w
    };
    let plant = GeneralizedPlant {
        a: ad,
        b1: b1d,
        b2: b2d,
        c1: widen(&c1),
        c2: widen(&c2),
        d12,
        d21: d21 * sigma,
    };
    let k = h2syn_discrete(&plant.balanced())?;
    Ok(Design {
        controller: k.k,
        sample_rate_hz: fs,
        h2_norm: k.h2_norm,
        spectral_radius: k.spectral_radius,
        made_for: run_config::made_for_plant(&plan.config.plant),
        stability: None,
        warnings: keyed(&k.warnings, "the thesis's noise weights (ThesisWeights)"),
    })
}
