//! The discrete simulator: the continuous model integrated exactly across each servo tick.
//!
//! Within tick k (from `t_k` to `t_k + T`) the DAC command of the previous tick acts for the
//! transport delay τ and the new one for `T − τ`; the cutting force and the white noises are
//! held over the tick (band-limited white noise: variance `fs/2` for a unit one-sided PSD, so
//! the spectrum is exact up to the `sinc²` of the hold); the sensor noise is a continuous
//! process sampled by each conversion ([`crate::sensor_noise`]). Every map from the state at
//! `t_k` to the next state, to the ADC conversions inside the tick and to the truth at
//! `t_k + T` is a matrix computed once from matrix exponentials; [`Simulator::step`] is a few dense
//! matrix-vector products and allocates nothing.

use crate::coil_loop::CoilLoop;
use crate::convert::Quantizer;
use crate::cutting::{CuttingError, CuttingForce, CuttingProfile};
use crate::gaussian::Gaussian;
use crate::model::{check, input, output, within, ModelError, PlantModel};
use crate::params::{CurrentLoopModel, PlantParams};
#[cfg(feature = "linear")]
use crate::quantisation::{averaged_rounding_error, ConversionGrid};
#[cfg(feature = "linear")]
use crate::sampled_noise::SampledNoise;
use crate::sensor_noise::SensorNoise;
use crate::tick_matrix::TickMatrix;
use daq_io::{flags, Sensor, Truth};
use lti::zoh;
use nalgebra::DMatrix;

/// How the stage's masses move at the end of the last tick (what the truth record,
/// [`daq_io::Truth`], leaves out).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageMotion {
    /// Absolute positions x1..x4 in m.
    pub x_m: [f64; 4],
    /// Absolute velocities v1..v4 in m/s.
    pub v_m_s: [f64; 4],
    /// Absolute acceleration of m2 in m/s².
    pub accel_m2_m_s2: f64,
}

/// One tick as a linear system, in the simulator's balanced state coordinates, with the
/// inputs `[u[k−1], u[k], f_cut, w_i, w_g, w_a]` (DAC command before and after the delay in V,
/// cutting force in N, and the unit white inputs of the current, base and accelerometer noise
/// filters, held over the tick):
///
/// ```text
/// x⁺ = phi·x + g·inputs
/// [gap_v, accel_v] = y_x·x + y_in·inputs + [sensor noise, 0]      (the sample closing the tick)
/// truth            = t_x·x + t_in·inputs                          (at the tick end)
/// ```
///
/// The held white inputs have variance `white_variance` per tick (a one-sided PSD of 1/Hz);
/// the averaged sensor noise on the gap reading is the coloured process `sensor_noise` (None
/// when that noise is off).
#[cfg(feature = "linear")]
#[derive(Debug, Clone)]
pub struct LinearTick {
    /// State transition over one tick (n × n).
    pub phi: DMatrix<f64>,
    /// Input matrix (n × 6).
    pub g: DMatrix<f64>,
    /// Averaged readings from the tick-start state (2 × n).
    pub y_x: DMatrix<f64>,
    /// Averaged readings from the inputs (2 × 6).
    pub y_in: DMatrix<f64>,
    /// Truth rows [`LinearTick::TRUTH`] from the tick-start state (7 × n).
    pub t_x: DMatrix<f64>,
    /// Truth rows from the inputs (7 × 6).
    pub t_in: DMatrix<f64>,
    /// Truth rows at the tick start from the state at the tick start (7 × n, the continuous
    /// model's output rows; their feed-through from the held inputs is zero for positions).
    pub t_start: DMatrix<f64>,
    /// Variance per tick of each held white input (`fs/2`), or 0 for a source that is off:
    /// `[current, base, accelerometer]`.
    pub white_variance: [f64; 3],
    /// The averaged sensor noise on the gap reading, V (a discrete process in innovations
    /// form with the simulator's spectrum), or None when that noise is off.
    pub sensor_noise: Option<SampledNoise>,
    /// The ADC's rounding error on the averaged gap reading, V: coloured by the sensor noise
    /// that dithers it ([`crate::quantisation`]); None for an ideal converter.
    pub gap_quantisation: Option<SampledNoise>,
    /// Variance per tick of the ADC's rounding error on the averaged accelerometer reading,
    /// V², its conversions taken as independent (`LSB²/12/oversampling`; 0 for an ideal
    /// converter).
    pub accel_quantisation_variance: f64,
    /// Variance of the DAC quantisation error on the command, V² (`LSB²/12`).
    pub dac_quantisation_variance: f64,
}

#[cfg(feature = "linear")]
impl LinearTick {
    /// Input columns.
    pub const INPUTS: [&'static str; 6] =
        ["u_prev", "u_now", "f_cut", "w_current", "w_base", "w_accel"];
    /// Truth rows: the model's output names (`model::output::NAMES`) of the truth signals.
    pub const TRUTH: [&'static str; TRUTH_ROWS.len()] = {
        let mut names = [""; TRUTH_ROWS.len()];
        let mut i = 0;
        while i < names.len() {
            names[i] = output::NAMES[TRUTH_ROWS[i]];
            i += 1;
        }
        names
    };
}

/// Simulator construction errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimError {
    /// Model parameters.
    #[error(transparent)]
    Model(#[from] ModelError),
    /// Cutting profile.
    #[error(transparent)]
    Cutting(#[from] CuttingError),
}

/// Held inputs of a tick besides the command: cutting force and the three white noises.
const HELD: usize = 4;
/// Truth outputs computed by matrix rows.
const TRUTH_ROWS: [usize; 7] = [
    output::TOOL_M,
    output::GAP_M,
    output::MOTOR_FORCE_N,
    output::COIL_CURRENT_A,
    output::CURRENT_NOISE_A,
    output::BASE_M,
    output::ACCEL_M2_M_S2,
];

/// The intervals of constant command input within a tick (s, from the tick): for the ideal
/// loop the previous DAC value until the delay and the new one after; for the coil model the
/// electrical sub-steps, split so that the delay falls on a boundary.
fn command_intervals(p: &PlantParams) -> Vec<(f64, f64)> {
    let (t, tau) = (p.period_s(), p.timing.delay_s);
    match p.actuator.model {
        CurrentLoopModel::Ideal => vec![(0.0, tau), (tau, t)],
        CurrentLoopModel::Coil => {
            let n = p.actuator.coil.substeps.max(2) as usize;
            let before =
                ((n as f64 * tau / t).round() as usize).clamp(usize::from(tau > 0.0), n - 1);
            let grid = |a: f64, b: f64, k: usize| {
                (0..k).map(move |i| {
                    (
                        a + (b - a) * i as f64 / k as f64,
                        a + (b - a) * (i + 1) as f64 / k as f64,
                    )
                })
            };
            grid(0.0, tau, before)
                .chain(grid(tau, t, n - before))
                .collect()
        }
    }
}

/// `[a | b | c | d]` side by side.
fn hstack(parts: &[&DMatrix<f64>]) -> DMatrix<f64> {
    let rows = parts[0].nrows();
    let cols: usize = parts.iter().map(|p| p.ncols()).sum();
    let mut m = DMatrix::zeros(rows, cols);
    let mut c0 = 0;
    for p in parts {
        m.view_mut((0, c0), (rows, p.ncols())).copy_from(p);
        c0 += p.ncols();
    }
    m
}

/// Exact propagation inside a tick whose command input (input 0) is constant on each of a
/// list of intervals `[start, end)` (two for the ideal loop: before and after the delay; one
/// per electrical sub-step for the coil model) while the other inputs are held all tick.
struct Propagator<'a> {
    a: &'a DMatrix<f64>,
    b: &'a DMatrix<f64>,
    intervals: &'a [(f64, f64)],
}

impl Propagator<'_> {
    /// State at time `s` as `[Φ(s) | one column per interval | held inputs]` acting on
    /// `[x_k, interval values, held]`.
    fn at(&self, s: f64) -> DMatrix<f64> {
        let n = self.a.nrows();
        let (phi, g) = zoh(self.a, self.b, s);
        let mut cols = vec![phi, DMatrix::zeros(n, 0)];
        for &(start, end) in self.intervals {
            let col = if s <= start {
                DMatrix::zeros(n, 1)
            } else {
                let end = end.min(s);
                let (after, _) = zoh(self.a, self.b, s - end);
                let (_, during) = zoh(self.a, self.b, end - start);
                after * during.columns(input::COMMAND_V, 1)
            };
            cols.push(col);
        }
        cols.push(g.columns(1, HELD).into_owned());
        hstack(&cols.iter().collect::<Vec<_>>())
    }

    /// The feed-through of output rows `d` at time `s`: the command acts through the interval
    /// that contains `s` (the earlier one at a boundary), the held inputs always.
    fn feedthrough(&self, d: &DMatrix<f64>, s: f64) -> DMatrix<f64> {
        let active = self
            .intervals
            .iter()
            .position(|&(a, b)| s > a && s <= b)
            .unwrap_or(0);
        let mut cmd = DMatrix::zeros(d.nrows(), self.intervals.len());
        cmd.column_mut(active)
            .copy_from(&d.column(input::COMMAND_V));
        hstack(&[&cmd, &d.columns(1, HELD).into_owned()])
    }
}

/// A change of the command between the DAC and the current amplifier: `u·scale + offset_v` (V).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CommandChange {
    /// Gain on the DAC's output (1: none).
    pub scale: f64,
    /// Added after the gain, V.
    pub offset_v: f64,
}

impl CommandChange {
    /// No change: `u·1 + (−0)` is `u` for every `u` (−0 is the additive identity, +0 is not:
    /// `−0 + 0 = +0`), so the plain step compiles to no arithmetic at all and keeps its bits.
    pub const NONE: CommandChange = CommandChange {
        scale: 1.0,
        offset_v: -0.0,
    };
}

/// The running simulator.
#[derive(Debug, Clone)]
pub struct Simulator {
    params: PlantParams,
    n: usize,
    tick_matrix: TickMatrix,
    /// `[x_k, command per interval, held inputs]`; the state lives in the first `n` entries.
    z: Vec<f64>,
    /// Output of the tick matrix.
    out: Vec<f64>,
    oversampling: usize,
    mech: std::ops::Range<usize>,
    /// Truth rows of the continuous model at the tick start (for [`Simulator::linear_tick`]).
    #[cfg(feature = "linear")]
    truth_start: DMatrix<f64>,
    /// Balancing scale of the mechanics states (state = scale · stored value).
    mech_scale: [f64; 8],
    u_prev: f64,
    intervals: Vec<(f64, f64)>,
    coil: Option<CoilLoop>,
    adc_q: Quantizer,
    dac_q: Quantizer,
    white_sigma: f64,
    sensor_noise: Option<SensorNoise>,
    noise_on: [bool; 3],
    cutting: CuttingForce,
    gaussian: Gaussian,
    tick: u64,
    period_s: f64,
    /// The contract's truth of the last [`Simulator::step_sensor`] (what
    /// [`daq_io::Backend::truth`] returns).
    pub(crate) last_truth: Truth,
}

impl Simulator {
    /// Builds the simulator for `params`, noise seeded by `seed`, with a cutting profile.
    pub fn new(
        params: &PlantParams,
        seed: u64,
        cutting: &CuttingProfile,
    ) -> Result<Self, SimError> {
        let t = &params.timing;
        let adc = &params.adc;
        for (key, value) in [
            ("timing.servo_rate_hz", t.servo_rate_hz),
            ("timing.delay_s", t.delay_s),
            ("adc.bits", adc.bits as f64), // 0 = ideal
            ("adc.range_v", adc.range_v),
            ("adc.conversion_rate_hz", adc.conversion_rate_hz),
            ("adc.oversampling", adc.oversampling as f64),
            ("dac.bits", params.dac.bits as f64),
            ("dac.range_v", params.dac.range_v),
        ] {
            check(key, value)?;
        }
        let period = 1.0 / t.servo_rate_hz;
        within(
            "timing.delay_s",
            t.delay_s,
            0.0,
            period,
            &format!("[0, {period:e}] s (one servo period)"),
        )?;
        let conversions = (period * adc.conversion_rate_hz).floor() + 1.0;
        within(
            "adc.oversampling",
            adc.oversampling as f64,
            1.0,
            conversions,
            &format!("[1, {conversions}] (the conversions in one servo period)"),
        )?;

        let model = PlantModel::new(params)?;
        // Balance the assembled model (mechanics at 10 Hz next to a 400 kHz current loop);
        // keep the scaling to read the masses' states back in metres.
        let (sys, scale) = model.sys.balance();
        let mech_scale = std::array::from_fn(|i| scale[model.mechanics.start + i]);
        let (a, b, c, d) = (&sys.a, &sys.b, &sys.c, &sys.d);
        let intervals = command_intervals(params);
        let prop = Propagator {
            a,
            b,
            intervals: &intervals,
        };
        let pick = |m: &DMatrix<f64>, rows: &[usize]| {
            DMatrix::from_fn(rows.len(), m.ncols(), |i, j| m[(rows[i], j)])
        };
        // `rows` of the outputs at time `s` as a map of `[x_k, intervals, held]`.
        let outputs_at = |rows: &[usize], s: f64| {
            let (cr, dr) = (pick(c, rows), pick(d, rows));
            let state = &cr * prop.at(s);
            let mut direct = DMatrix::zeros(rows.len(), a.nrows());
            direct = hstack(&[&direct, &prop.feedthrough(&dr, s)]);
            state + direct
        };
        // Next state, then the ADC conversions (the last at the tick end, the others
        // 1/f_adc apart before it), then the truth at the tick end (left limit).
        let mut blocks = vec![prop.at(period)];
        for j in 0..adc.oversampling {
            let s = period - (adc.oversampling - 1 - j) as f64 / adc.conversion_rate_hz;
            blocks.push(outputs_at(&[output::SENSOR_V, output::ACCEL_V], s));
        }
        blocks.push(outputs_at(&TRUTH_ROWS, period));
        let tick_matrix = TickMatrix::new(&blocks);
        let coil = (params.actuator.model == CurrentLoopModel::Coil).then(|| {
            let velocity = c.row(output::COIL_VELOCITY_M_S).iter().copied().collect();
            let before = intervals.iter().filter(|iv| iv.1 <= t.delay_s).count();
            CoilLoop::new(params, velocity, before)
        });
        let n = a.nrows();
        let fs = t.servo_rate_hz;
        let noise = &params.noise;
        Ok(Simulator {
            params: *params,
            n,
            out: vec![0.0; tick_matrix.rows],
            z: vec![0.0; n + intervals.len() + HELD],
            tick_matrix,
            oversampling: adc.oversampling as usize,
            mech: model.mechanics,
            #[cfg(feature = "linear")]
            truth_start: pick(c, &TRUTH_ROWS),
            mech_scale,
            u_prev: 0.0,
            coil,
            intervals,
            adc_q: Quantizer::new(adc.bits, adc.range_v),
            dac_q: Quantizer::new(params.dac.bits, params.dac.range_v),
            white_sigma: (fs / 2.0).sqrt(),
            sensor_noise: (noise.sensor && noise.sensor_v_per_rt_hz > 0.0).then(|| {
                SensorNoise::new(
                    noise.sensor_v_per_rt_hz,
                    params.capa.bandwidth_hz,
                    adc.anti_alias_hz,
                    period,
                    adc.oversampling,
                    adc.conversion_rate_hz,
                )
            }),
            noise_on: [noise.current, noise.base, noise.accel],
            cutting: CuttingForce::new(cutting)?,
            gaussian: Gaussian::new(seed),
            tick: 0,
            period_s: period,
            last_truth: Truth::default(),
        })
    }

    /// The parameters in use.
    pub fn params(&self) -> &PlantParams {
        &self.params
    }

    /// Servo period in s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The tick as a linear map from the command, for stability analysis: `None` for the
    /// nonlinear `coil` model. Noise and cutting inputs are left out (they do not affect
    /// stability).
    #[cfg(feature = "linear")]
    pub fn linear_tick(&self) -> Option<LinearTick> {
        if self.coil.is_some() {
            return None;
        }
        let (n, rows, os) = (self.n, self.tick_matrix.rows, self.oversampling);
        let entry = |i: usize, j: usize| self.tick_matrix.cols[j * rows + i];
        let avg = |ch: usize, j: usize| {
            (0..os).map(|c| entry(n + 2 * c + ch, j)).sum::<f64>() / os as f64
        };
        let truth = |r: usize, j: usize| entry(n + 2 * os + r, j);
        let inputs = LinearTick::INPUTS.len();
        let var = |on: bool| {
            if on {
                self.white_sigma * self.white_sigma
            } else {
                0.0
            }
        };
        Some(LinearTick {
            phi: DMatrix::from_fn(n, n, &entry),
            g: DMatrix::from_fn(n, inputs, |i, j| entry(i, n + j)),
            y_x: DMatrix::from_fn(2, n, &avg),
            y_in: DMatrix::from_fn(2, inputs, |ch, j| avg(ch, n + j)),
            t_x: DMatrix::from_fn(TRUTH_ROWS.len(), n, &truth),
            t_in: DMatrix::from_fn(TRUTH_ROWS.len(), inputs, |r, j| truth(r, n + j)),
            t_start: self.truth_start.clone(),
            white_variance: [
                var(self.noise_on[0]),
                var(self.noise_on[1]),
                var(self.noise_on[2]),
            ],
            sensor_noise: self.sensor_noise.map(|s| s.sampled(os as u32)),
            gap_quantisation: averaged_rounding_error(
                self.adc_q.lsb_v(),
                self.sensor_noise.as_ref(),
                &ConversionGrid {
                    period_s: self.period_s,
                    oversampling: os as u32,
                    conversion_rate_hz: self.params.adc.conversion_rate_hz,
                },
            ),
            accel_quantisation_variance: self.adc_q.lsb_v().powi(2) / 12.0 / os as f64,
            dac_quantisation_variance: self.dac_q.lsb_v().powi(2) / 12.0,
        })
    }

    /// Number of continuous states.
    pub fn state_len(&self) -> usize {
        self.n
    }

    /// The DAC converter (18 bit ±10 V by default).
    pub fn dac(&self) -> &Quantizer {
        &self.dac_q
    }

    /// The ADC converter (16 bit ±4.096 V by default).
    pub fn adc(&self) -> &Quantizer {
        &self.adc_q
    }

    #[inline]
    fn gauss(&mut self) -> f64 {
        self.gaussian.sample()
    }

    /// Runs one tick: `command_v` goes to the DAC now and reaches the coil τ later. Returns the
    /// ADC readings closing the tick (the controller's next input: the mean of the oversampled
    /// conversions, the converters' flags) and the truth at that time, as the sample contract
    /// has them (`seq`, the encoder count and the run's identity left to the transport);
    /// [`Simulator::motion`] has the masses' motion.
    #[inline]
    pub fn step(&mut self, command_v: f64) -> (Sensor, Truth) {
        self.step_with_force(command_v, 0.0)
    }

    /// [`Simulator::step`] with `extra_force_n` (N, positive away from the workpiece, held over
    /// the tick) added to the configured cutting profile: the force of a cut the caller
    /// models (a freeform surface at the spindle position).
    pub fn step_with_force(&mut self, command_v: f64, extra_force_n: f64) -> (Sensor, Truth) {
        self.step_changed(command_v, extra_force_n, CommandChange::NONE)
    }

    /// [`Simulator::step_with_force`] with the DAC's output changed on its way to the current
    /// amplifier by `change` (what a practice stage does to model a force constant that varies
    /// with position, or a force the linear model lacks); the truth's `dac_v` stays the DAC's.
    #[inline(always)]
    pub(crate) fn step_changed(
        &mut self,
        command_v: f64,
        extra_force_n: f64,
        change: CommandChange,
    ) -> (Sensor, Truth) {
        let mut flag = 0;
        let (u_now, clipped) = self.dac_q.convert(command_v);
        let u_now = if command_v.is_finite() {
            flag |= if clipped { flags::DAC_CLIPPED } else { 0 };
            u_now
        } else {
            flag |= flags::COMMAND_NOT_FINITE;
            0.0
        };
        let dac_v = u_now;
        let u_now = u_now * change.scale + change.offset_v;
        let t = self.tick as f64 * self.period_s;
        let extra = if extra_force_n.is_finite() {
            extra_force_n
        } else {
            0.0
        };
        let f_cut = self.cutting.at(t) + extra;
        let n = self.n;
        let k = self.intervals.len();
        match &mut self.coil {
            None => {
                self.z[n] = self.u_prev;
                self.z[n + 1] = u_now;
            }
            Some(coil) => {
                let (x, currents) = self.z.split_at_mut(n);
                coil.tick(&self.intervals, self.u_prev, u_now, x, &mut currents[..k]);
            }
        }
        self.z[n + k] = f_cut;
        for (i, on) in self.noise_on.into_iter().enumerate() {
            self.z[n + k + 1 + i] = if on {
                self.white_sigma * self.gauss()
            } else {
                0.0
            };
        }
        self.tick_matrix.apply(&self.z, &mut self.out);
        // Conversions inside the tick (rows n.. of the product), with sensor noise on the gap.
        let mut noise_sum = 0.0;
        let (mut gap_v, mut acc_v) = (0.0, 0.0);
        for j in 0..self.oversampling {
            let noise = match &mut self.sensor_noise {
                Some(s) => s.next(j == 0, || self.gaussian.sample()),
                None => 0.0,
            };
            noise_sum += noise;
            let (gv, gc) = self.adc_q.convert(self.out[n + 2 * j] + noise);
            let (av, ac) = self.adc_q.convert(self.out[n + 2 * j + 1]);
            (gap_v, acc_v) = (gap_v + gv, acc_v + av);
            flag |=
                if gc { flags::GAP_CLIPPED } else { 0 } | if ac { flags::ACCEL_CLIPPED } else { 0 };
        }
        self.z[..n].copy_from_slice(&self.out[..n]);
        self.u_prev = u_now;
        self.tick += 1;

        let k = self.oversampling as f64;
        let sample = Sensor {
            time_s: self.tick as f64 * self.period_s,
            gap_v: gap_v / k,
            accel_v: acc_v / k,
            flags: flag,
            ..Default::default()
        };
        let tr = &self.out[n + 2 * self.oversampling..];
        // The coil model's current comes from its ODE (the matrix saw sub-step means).
        let (coil_current, motor_force) = match &self.coil {
            None => (tr[3], tr[2]),
            Some(c) => (c.i, c.kt * (c.i + tr[4])),
        };
        let truth = Truth {
            seq: 0,
            time_s: sample.time_s,
            tool_m: tr[0],
            gap_m: tr[1],
            motor_force_n: motor_force,
            cutting_force_n: f_cut,
            coil_current_a: coil_current,
            current_noise_a: tr[4],
            base_m: tr[5],
            sensor_noise_v: noise_sum / k,
            dac_v,
            flags: 0,
            reserved: 0,
        };
        (sample, truth)
    }

    /// How the masses move at the end of the last tick (at rest before the first).
    pub fn motion(&self) -> StageMotion {
        let (m, x) = (self.mech.start, &self.z);
        StageMotion {
            x_m: std::array::from_fn(|i| x[m + i] * self.mech_scale[i]),
            v_m_s: std::array::from_fn(|i| x[m + 4 + i] * self.mech_scale[4 + i]),
            accel_m2_m_s2: self.out[self.n + 2 * self.oversampling + 6],
        }
    }

    /// Back to rest at t = 0 with the noise generator reseeded.
    pub fn reset(&mut self, seed: u64) {
        self.z.iter_mut().for_each(|x| *x = 0.0);
        if let Some(c) = &mut self.coil {
            (c.i, c.q) = (0.0, 0.0);
        }
        if let Some(s) = &mut self.sensor_noise {
            s.reset();
        }
        self.u_prev = 0.0;
        self.tick = 0;
        self.gaussian = Gaussian::new(seed);
    }
}
