//! H2-optimal controller design on the simulator's exact discrete model (thesis Ch. 6, in the
//! spirit of Fig 6-3 but with the plant the simulator runs): the noise shaping filters are
//! already in the model, so the controller directly minimises the variance of the **true** tool
//! position (z1, in nm) plus `ρ²·u²` (z2), given the sensor, current, base and converter noise.
//! The transport delay, the hold and the ADC averaging are in the tick, so the design knows
//! them (DESIGN.md, "Discrete controllers are designed knowing this delay").

use crate::error::StudyError;
use design::h2::{h2syn_discrete, GeneralizedPlant};
use lti::StateSpace;
use nalgebra::DMatrix;
use plant_sim::sensor_noise::SampledSensorNoise;
use runner::config::MadeFor;
use runner::Plan;

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
             sample_rate_hz = {}\na = {}\nb = {}\nc = {}\nd = {}\n\n{}",
            k.nx(),
            self.h2_norm,
            self.spectral_radius,
            self.sample_rate_hz,
            rows(&k.a),
            rows(&k.b),
            rows(&k.c),
            rows(&k.d),
            self.made_for.to_toml("made_for")
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
    // State [x, u[k−1], gap reading, sensor-noise state].
    let (iu, iy, is) = (n, n + 1, n + 2);
    let size = is
        + t.sensor_noise
            .as_ref()
            .map_or(0, SampledSensorNoise::states);
    let sigma_w = t.white_variance.map(f64::sqrt);
    let sigma_s = t
        .sensor_noise
        .as_ref()
        .map_or(0.0, |s| s.variance.sqrt() * sensor_noise_scale);
    // Measurement noise on the reading: the ADC's quantisation (a floor keeps D21 full rank for
    // an ideal converter).
    let sigma_q = t
        .adc_quantisation_variance
        .sqrt()
        .max(1e-3 * sigma_s)
        .max(1e-12);
    // w = [sensor innovation, current, base, accelerometer, quantisation], unit variance.
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
    let mut c2 = DMatrix::zeros(1, size);
    c2[(0, iy)] = 1.0;
    let mut d21 = DMatrix::zeros(1, nw);
    d21[(0, 4)] = sigma_q;
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
        made_for: runner::config::made_for_plant(&plan.config.plant),
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
        made_for: runner::config::made_for_plant(&plan.config.plant),
    })
}
