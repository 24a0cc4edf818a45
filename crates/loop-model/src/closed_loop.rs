//! The sampled closed loop (the simulator's exact linear tick + the controller's realisation)
//! as one discrete state space: stability, frequency responses, bandwidth. The error budget
//! built on it lives in the `studies` crate.

use crate::controller::LinearController;
use lti::{LtiError, StateSpace};
use nalgebra::DMatrix;
use plant_sim::sampled_noise::SampledNoise;
use plant_sim::LinearTick;

/// Inputs of [`ClosedLoop::sys`].
pub mod input {
    /// Reference position in m.
    pub const REFERENCE_M: usize = 0;
    /// Innovation of the sensor noise on the averaged gap reading, V (per-tick white; the
    /// noise itself is coloured, `plant_sim::sampled_noise::SampledNoise`).
    pub const SENSOR_NOISE_V: usize = 1;
    /// Cutting force on the tool in N.
    pub const CUTTING_FORCE_N: usize = 2;
    /// Unit white input of the current-noise filter.
    pub const W_CURRENT: usize = 3;
    /// Unit white input of the base-vibration filter.
    pub const W_BASE: usize = 4;
    /// Unit white input of the accelerometer-noise filter.
    pub const W_ACCEL: usize = 5;
    /// Disturbance added to the controller output, V (the FRF injection point, §5.7.5).
    pub const CONTROL_DISTURBANCE_V: usize = 6;
    /// Error on the averaged accelerometer reading, V (its ADC quantisation).
    pub const ACCEL_READING_V: usize = 7;
    /// Innovation of the ADC's rounding error on the averaged gap reading, V (per-tick white;
    /// the error itself is coloured, `plant_sim::quantisation`).
    pub const GAP_READING_V: usize = 8;
    /// Count.
    pub const COUNT: usize = 9;
    /// Names, in order, with units.
    pub const NAMES: [&str; COUNT] = [
        "reference_m",
        "sensor_noise_innovation_v",
        "cutting_force_n",
        "current_white",
        "base_white",
        "accel_white",
        "control_disturbance_v",
        "accel_reading_error_v",
        "gap_reading_error_innovation_v",
    ];
}

/// Outputs of [`ClosedLoop::sys`].
pub mod output {
    /// Following error `r − measured` in m (what the sensor reports).
    pub const FOLLOWING_ERROR_M: usize = 0;
    /// True tool error `tool − r` in m (at the end of the tick).
    pub const TRUE_ERROR_M: usize = 1;
    /// Controller output (DAC command) in V.
    pub const CONTROL_V: usize = 2;
    /// Measured position `gap_v / S_capa` in m.
    pub const MEASURED_M: usize = 3;
    /// Tool position relative to the frame in m.
    pub const TOOL_M: usize = 4;
    /// The averaged accelerometer reading the controller takes, V.
    pub const ACCEL_READING_V: usize = 5;
    /// Count.
    pub const COUNT: usize = 6;
    /// Names, in order, with units.
    pub const NAMES: [&str; COUNT] = [
        "following_error_m",
        "true_error_m",
        "control_v",
        "measured_m",
        "tool_m",
        "accel_reading_v",
    ];
}

/// The smallest Hankel singular value, relative to the largest, of a state
/// [`ClosedLoop::slowest_command_pole`] counts as seen in the response.
const VISIBLE_HANKEL: f64 = 1e-9;

/// The sampled closed loop.
#[derive(Debug, Clone)]
pub struct ClosedLoop {
    /// Discrete state space (period `period_s`): inputs [`input`], outputs [`output`].
    pub sys: StateSpace,
    /// Servo period in s.
    pub period_s: f64,
    /// Per-tick variance of each input of [`SOURCES`], in that order.
    pub noise_variance: [f64; 7],
}

impl ClosedLoop {
    /// Closes the loop around `plant` with `ctrl`; `sensitivity_v_per_m` converts the gap
    /// reading to metres (the reference enters the controller as `S·r`).
    ///
    /// State `[x, u[k−1], controller state, last sample (gap, accel), sensor-noise state,
    /// gap-quantisation state]`;
    /// at tick k `u = C c + D (y − [S r, 0]) + d_u`.
    pub fn new(
        plant: &LinearTick,
        ctrl: &LinearController,
        sensitivity_v_per_m: f64,
        period_s: f64,
    ) -> Self {
        Self::assemble(plant, ctrl, sensitivity_v_per_m, period_s, false)
    }

    /// The same loop, same state, while its controller is stalled (a descheduled controller
    /// process in a real-time run): the DAC holds the last command (`u = u[k−1]`, no DAC
    /// disturbance), the controller's state is frozen and the reference does not reach it; the
    /// stage, its readings and the noise go on. Ticking [`ClosedLoop::new`]'s matrices again
    /// afterwards is the controller taking the newest sample.
    pub fn held(
        plant: &LinearTick,
        ctrl: &LinearController,
        sensitivity_v_per_m: f64,
        period_s: f64,
    ) -> Self {
        Self::assemble(plant, ctrl, sensitivity_v_per_m, period_s, true)
    }

    fn assemble(
        plant: &LinearTick,
        ctrl: &LinearController,
        sensitivity_v_per_m: f64,
        period_s: f64,
        stalled: bool,
    ) -> Self {
        let s = sensitivity_v_per_m;
        let (n, nc) = (plant.phi.nrows(), ctrl.a.nrows());
        let (iu, ic, iy) = (n, n + 1, n + 1 + nc);
        let is = iy + 2;
        let iq = is + plant.sensor_noise.as_ref().map_or(0, SampledNoise::states);
        let size = iq
            + plant
                .gap_quantisation
                .as_ref()
                .map_or(0, SampledNoise::states);
        let m = input::COUNT;
        // u as rows over the state and over the inputs.
        let mut u_z = DMatrix::zeros(1, size);
        let mut u_in = DMatrix::zeros(1, m);
        if stalled {
            u_z[(0, iu)] = 1.0;
        } else {
            u_z.view_mut((0, ic), (1, nc)).copy_from(&ctrl.c);
            u_z.view_mut((0, iy), (1, 2)).copy_from(&ctrl.d);
            u_in[(0, input::REFERENCE_M)] = -ctrl.d[(0, 0)] * s;
            u_in[(0, input::CONTROL_DISTURBANCE_V)] = 1.0;
        }
        // Plant inputs other than the command, mapped from the loop inputs (f_cut, w…).
        let held = |g: &DMatrix<f64>| {
            let mut out = DMatrix::zeros(g.nrows(), m);
            for (k, col) in [
                input::CUTTING_FORCE_N,
                input::W_CURRENT,
                input::W_BASE,
                input::W_ACCEL,
            ]
            .into_iter()
            .enumerate()
            {
                out.column_mut(col).copy_from(&g.column(2 + k));
            }
            out
        };
        let mut a = DMatrix::zeros(size, size);
        let mut b = DMatrix::zeros(size, m);
        // x⁺ = Φx + g0 u_prev + g1 u + g_held w
        a.view_mut((0, 0), (n, n)).copy_from(&plant.phi);
        a.view_mut((0, iu), (n, 1)).copy_from(&plant.g.column(0));
        a.view_mut((0, 0), (n, size))
            .zip_apply(&(plant.g.column(1) * &u_z), |x, y| *x += y);
        b.view_mut((0, 0), (n, m))
            .copy_from(&(plant.g.column(1) * &u_in + held(&plant.g)));
        // u_prev⁺ = u
        a.view_mut((iu, 0), (1, size)).copy_from(&u_z);
        b.view_mut((iu, 0), (1, m)).copy_from(&u_in);
        // c⁺ = A c + B (y − [S r, 0]); stalled: c⁺ = c
        if stalled {
            a.view_mut((ic, ic), (nc, nc)).fill_with_identity();
        } else {
            a.view_mut((ic, ic), (nc, nc)).copy_from(&ctrl.a);
            a.view_mut((ic, iy), (nc, 2)).copy_from(&ctrl.b);
            b.view_mut((ic, input::REFERENCE_M), (nc, 1))
                .copy_from(&(ctrl.b.column(0) * -s));
        }
        // y⁺ = y_x x + y0 u_prev + y1 u + y_held w + [n_s, 0]
        a.view_mut((iy, 0), (2, n)).copy_from(&plant.y_x);
        a.view_mut((iy, iu), (2, 1))
            .copy_from(&plant.y_in.column(0));
        a.view_mut((iy, 0), (2, size))
            .zip_apply(&(plant.y_in.column(1) * &u_z), |x, y| *x += y);
        b.view_mut((iy, 0), (2, m))
            .copy_from(&(plant.y_in.column(1) * &u_in + held(&plant.y_in)));
        // Sensor noise n = c ξ + e, ξ⁺ = a ξ + k e (on the gap reading), then the converters'.
        if let Some(sn) = &plant.sensor_noise {
            sn.place(&mut a, &mut b, (iy, is, input::SENSOR_NOISE_V), 1.0);
        }
        if let Some(q) = &plant.gap_quantisation {
            q.place(&mut a, &mut b, (iy, iq, input::GAP_READING_V), 1.0);
        }
        b[(iy + 1, input::ACCEL_READING_V)] = 1.0;
        // Outputs.
        let mut c = DMatrix::zeros(output::COUNT, size);
        let mut d = DMatrix::zeros(output::COUNT, m);
        c[(output::FOLLOWING_ERROR_M, iy)] = -1.0 / s;
        d[(output::FOLLOWING_ERROR_M, input::REFERENCE_M)] = 1.0;
        c[(output::MEASURED_M, iy)] = 1.0 / s;
        c[(output::ACCEL_READING_V, iy + 1)] = 1.0;
        c.row_mut(output::CONTROL_V).copy_from(&u_z);
        d.row_mut(output::CONTROL_V).copy_from(&u_in);
        // tool at the tick end = t_x x + t0 u_prev + t1 u + t_held w
        let tool_z = {
            let mut r = DMatrix::zeros(1, size);
            r.view_mut((0, 0), (1, n)).copy_from(&plant.t_x.row(0));
            r[(0, iu)] = plant.t_in[(0, 0)];
            r + &u_z * plant.t_in[(0, 1)]
        };
        let tool_in = &u_in * plant.t_in[(0, 1)] + held(&plant.t_in.rows(0, 1).into_owned());
        c.row_mut(output::TOOL_M).copy_from(&tool_z);
        d.row_mut(output::TOOL_M).copy_from(&tool_in);
        c.row_mut(output::TRUE_ERROR_M).copy_from(&tool_z);
        d.row_mut(output::TRUE_ERROR_M).copy_from(&tool_in);
        d[(output::TRUE_ERROR_M, input::REFERENCE_M)] -= 1.0;
        let [wc, wb, wa] = plant.white_variance;
        ClosedLoop {
            sys: StateSpace { a, b, c, d },
            period_s,
            noise_variance: [
                plant.sensor_noise.as_ref().map_or(0.0, |s| s.variance),
                wc,
                wb,
                wa,
                plant.gap_quantisation.as_ref().map_or(0.0, |q| q.variance),
                plant.accel_quantisation_variance,
                plant.dac_quantisation_variance,
            ],
        }
    }

    /// Largest closed-loop pole magnitude (< 1: stable); NaN when a pole is not a number (a
    /// loop whose coefficients overflow), which no `< 1` check accepts.
    pub fn spectral_radius(&self) -> f64 {
        self.sys
            .poles()
            .iter()
            .map(|p| p.norm())
            .fold(
                0.0,
                |worst, r| if r.is_nan() || r > worst { r } else { worst },
            )
    }

    /// The plant of `sim` alone, no controller (the DAC command enters as
    /// [`input::CONTROL_DISTURBANCE_V`]); None for the `coil` current-loop model, which has no
    /// linear tick.
    pub fn open(sim: &plant_sim::Simulator, sensitivity_v_per_m: f64) -> Option<ClosedLoop> {
        Some(ClosedLoop::new(
            &sim.linear_tick()?,
            &LinearController::none(),
            sensitivity_v_per_m,
            sim.period_s(),
        ))
    }

    /// Measured position (m) per volt added to the controller output, at `f_hz` (the plant
    /// alone for [`ClosedLoop::open`]).
    pub fn command_response(&self, f_hz: f64) -> Result<num_complex::Complex64, LtiError> {
        self.response(output::MEASURED_M, input::CONTROL_DISTURBANCE_V, f_hz)
    }

    /// The slowest decaying pole (z-plane) the command response shows, if any: of the balanced
    /// realisation of the controller output → measured position, the states whose Hankel
    /// singular value is at least 10⁻⁹ of the largest. Its time constant `−T/ln|p|` is how
    /// long a transient the command starts rings. Ask it of a loop whose plant has its noise
    /// off: the discretisation's rounding reaches the noise shaping's slow states (1–3 s) from
    /// the command by ~10⁻²², which the gap sees enough to count.
    pub fn slowest_command_pole(&self) -> Result<Option<num_complex::Complex64>, LtiError> {
        let siso = self.subsystem(&[(output::MEASURED_M, 1.0)], input::CONTROL_DISTURBANCE_V);
        let balancing = lti::reduce::Balancing::new(&siso)?;
        let hankel = balancing.truncate(0).hankel;
        let largest = hankel.first().copied().unwrap_or(0.0);
        let visible = hankel
            .iter()
            .filter(|&&h| h >= VISIBLE_HANKEL * largest)
            .count();
        Ok(balancing
            .truncate(visible)
            .sys
            .poles()
            .into_iter()
            .max_by(|a, b| a.norm().total_cmp(&b.norm())))
    }

    /// [`ClosedLoop::command_response`] at each of `freq_hz` (the loop reduced once), each
    /// frequency's own result.
    pub fn command_responses(
        &self,
        freq_hz: &[f64],
    ) -> Vec<Result<num_complex::Complex64, LtiError>> {
        let siso = self.subsystem(&[(output::MEASURED_M, 1.0)], input::CONTROL_DISTURBANCE_V);
        let response = lti::FrequencyResponse::new(&siso);
        freq_hz
            .iter()
            .map(|&f| Ok(response.discrete(f, self.period_s)?[(0, 0)]))
            .collect()
    }

    /// `H(e^{j2πfT})` from `input` to `output`.
    pub fn response(
        &self,
        output: usize,
        input: usize,
        f_hz: f64,
    ) -> Result<num_complex::Complex64, LtiError> {
        Ok(self.sys.freq_response_discrete(f_hz, self.period_s)?[(output, input)])
    }

    /// The loop with only `outputs`, each output row scaled by its factor (every input).
    pub fn outputs(&self, outputs: &[(usize, f64)]) -> StateSpace {
        let rows = |m: &DMatrix<f64>| {
            DMatrix::from_fn(outputs.len(), m.ncols(), |i, j| {
                m[(outputs[i].0, j)] * outputs[i].1
            })
        };
        StateSpace {
            a: self.sys.a.clone(),
            b: self.sys.b.clone(),
            c: rows(&self.sys.c),
            d: rows(&self.sys.d),
        }
    }

    /// The single-input part of the loop from `input` to `outputs` (scaled as in
    /// [`ClosedLoop::outputs`]).
    pub fn subsystem(&self, outputs: &[(usize, f64)], input: usize) -> StateSpace {
        let mut sys = self.outputs(outputs);
        sys.b = sys.b.columns(input, 1).into_owned();
        sys.d = sys.d.columns(input, 1).into_owned();
        sys
    }

    /// The loop gain broken at the DAC command of this open loop ([`ClosedLoop::open`]) with
    /// controller `ctrl`: `L = −K·P`, `P` from the command (V) to the two readings the
    /// controller takes, `[gap_v, accel_v]` (V), and `K` the controller. Negative-feedback
    /// convention (the loop is `1 + L`); with acceleration feedback its inner loop is part of
    /// the break. `sensitivity_v_per_m` converts the measured position to the gap reading.
    pub fn loop_gain(
        &self,
        ctrl: &LinearController,
        sensitivity_v_per_m: f64,
    ) -> Result<StateSpace, LtiError> {
        let readings = self.subsystem(
            &[
                (output::MEASURED_M, sensitivity_v_per_m),
                (output::ACCEL_READING_V, 1.0),
            ],
            input::CONTROL_DISTURBANCE_V,
        );
        Ok(readings.series(&ctrl.state_space())?.scaled(-1.0))
    }

    /// Closed-loop bandwidth in Hz: the first frequency at which |T| (reference → measured
    /// position) falls below 1/√2 of its low-frequency gain — the first −3 dB crossing, found
    /// exactly ([`lti::level_crossing::first_fall_below`]: however narrow a dip that reaches
    /// it, e.g. at the m4 mode near 422 Hz), or Nyquist if |T| never falls that far. One
    /// definition for the budget, the sweeps, tuning and the studies.
    pub fn bandwidth_hz(&self) -> Result<f64, LtiError> {
        let siso = self.subsystem(&[(output::MEASURED_M, 1.0)], input::REFERENCE_M);
        let low = siso.freq_response_discrete(1e-3, self.period_s)?[(0, 0)].norm();
        Ok(
            lti::level_crossing::first_fall_below(&siso, self.period_s, low / 2f64.sqrt())?
                .unwrap_or(0.5 / self.period_s),
        )
    }
}

/// The noise sources of the budget and their loop inputs, in [`ClosedLoop::noise_variance`]
/// order: the thesis's three (sensor, current, base), the accelerometer (§7.5.2), and the
/// converters' quantisation (the gap reading's coloured by the sensor noise that dithers the
/// ADC, `plant_sim::quantisation`; the accelerometer reading's and the DAC's white).
pub const SOURCES: [(&str, usize); 7] = [
    ("sensor", input::SENSOR_NOISE_V),
    ("current", input::W_CURRENT),
    ("base", input::W_BASE),
    ("accelerometer", input::W_ACCEL),
    ("adc gap", input::GAP_READING_V),
    ("adc accel", input::ACCEL_READING_V),
    ("dac", input::CONTROL_DISTURBANCE_V),
];

/// The response of loop output `out` per metre added to the surface reference at `f` Hz,
/// through the reference path the tick applies (smoothing, feedforward: `deployment`'s) and
/// the closed loop `cl`; NaN where it cannot be evaluated.
pub fn reference_path_response<'a>(
    cl: &'a ClosedLoop,
    deployment: &'a servo_config::Deployment,
    out: usize,
) -> impl Fn(f64) -> num_complex::Complex64 + 'a {
    use num_complex::Complex64 as C;
    let to_output = |inp: usize| lti::FrequencyResponse::new(&cl.subsystem(&[(out, 1.0)], inp));
    let reference = to_output(input::REFERENCE_M);
    let command = to_output(input::CONTROL_DISTURBANCE_V);
    let period = cl.period_s;
    move |f| {
        let path = servo_config::reference_path(deployment, f);
        let c = |v: [f64; 2]| C::new(v[0], v[1]);
        let at = |r: &lti::FrequencyResponse| {
            r.discrete(f, period)
                .map(|m| m[(0, 0)])
                .unwrap_or(C::new(f64::NAN, f64::NAN))
        };
        at(&reference) * c(path.reference) + at(&command) * c(path.feedforward_v_per_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A loop whose matrix holds a NaN (coefficients that overflowed) has a NaN radius, which
    /// no `< 1` check accepts (`f64::max` used to drop it and report 0).
    #[test]
    fn a_loop_that_is_not_a_number_has_no_radius_below_one() {
        let n = 3;
        let mut a = DMatrix::identity(n, n) * 0.5;
        a[(1, 2)] = f64::NAN;
        let cl = ClosedLoop {
            sys: StateSpace {
                a,
                b: DMatrix::zeros(n, 0),
                c: DMatrix::zeros(0, n),
                d: DMatrix::zeros(0, 0),
            },
            period_s: 1e-5,
            noise_variance: [0.0; 7],
        };
        assert!(cl.spectral_radius().is_nan());
    }
}
