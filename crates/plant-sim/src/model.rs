//! The continuous-time model of the whole stage as one state space, assembled by named signals:
//! mechanics (DESIGN.md equations), current loop (eq 5-9), motor, capacitive sensor (eq 5-8),
//! accelerometer chain (Table 7-2) and the noise shaping filters (eq 6-6..6-8, Table 7-2).

use crate::limits::limit_of;
use crate::modes::ModeSite;
use crate::params::{rad, CurrentLoopModel, PlantParams, StageParams};
use lti::interconnect::{ConnectError, Interconnect, NamedBlock};
use lti::{LtiError, StateSpace};
use nalgebra::DMatrix;
use std::f64::consts::SQRT_2;
use std::ops::Range;

/// External inputs of [`PlantModel::sys`], in order.
pub mod input {
    /// Command to the current amplifier in V (after the DAC); with the `coil` current-loop
    /// model, the coil current in A instead (the electrical loop is simulated outside).
    pub const COMMAND_V: usize = 0;
    /// Cutting force on the tool tip m1 in N (positive away from the workpiece).
    pub const CUTTING_FORCE_N: usize = 1;
    /// Unit white noise (one-sided PSD 1/Hz) driving the current-noise filter Wi.
    pub const CURRENT_WHITE: usize = 2;
    /// Unit white noise driving the base-vibration filter Wg.
    pub const BASE_WHITE: usize = 3;
    /// Unit white noise driving the accelerometer-noise filter.
    pub const ACCEL_WHITE: usize = 4;
    /// Number of inputs.
    pub const COUNT: usize = 5;
    /// Signal names, in order.
    pub const NAMES: [&str; COUNT] = [
        "command_v",
        "cutting_force_n",
        "current_white",
        "base_white",
        "accel_white",
    ];
}

/// Outputs of [`PlantModel::sys`], in order.
pub mod output {
    /// Capacitive sensor voltage in V (noise-free, before the ADC).
    pub const SENSOR_V: usize = 0;
    /// Accelerometer voltage in V (with its own noise, before the ADC).
    pub const ACCEL_V: usize = 1;
    /// True tool position relative to the frame, `x1 − xg`, in m.
    pub const TOOL_M: usize = 2;
    /// Mechanical gap the sensor sees, `x2 − xg`, in m.
    pub const GAP_M: usize = 3;
    /// Motor force `K_T·(I + i_n)` in N.
    pub const MOTOR_FORCE_N: usize = 4;
    /// Coil current from the current loop in A (without the current noise).
    pub const COIL_CURRENT_A: usize = 5;
    /// Current noise i_n in A.
    pub const CURRENT_NOISE_A: usize = 6;
    /// Base displacement xg in m.
    pub const BASE_M: usize = 7;
    /// Absolute acceleration of m2 in m/s².
    pub const ACCEL_M2_M_S2: usize = 8;
    /// Coil velocity relative to the magnet, `v2 − v3`, in m/s (back-EMF = K_T·this).
    pub const COIL_VELOCITY_M_S: usize = 9;
    /// Number of outputs.
    pub const COUNT: usize = 10;
    /// Signal names, in order.
    pub const NAMES: [&str; COUNT] = [
        "sensor_v",
        "accel_v",
        "tool_m",
        "gap_m",
        "motor_force_n",
        "coil_current_a",
        "current_noise_a",
        "base_m",
        "accel_m2",
        "coil_velocity",
    ];
}

/// Model construction errors.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A parameter is outside its physical range.
    #[error("`{key}` = {value} is outside the allowed range {range}")]
    Parameter {
        /// Config key (dotted path).
        key: &'static str,
        /// Offending value.
        value: f64,
        /// Allowed range, human-readable.
        range: String,
    },
    /// Interconnection failure (a bug if it happens).
    #[error(transparent)]
    Connect(#[from] ConnectError),
    /// LTI failure.
    #[error(transparent)]
    Lti(#[from] LtiError),
}

/// The assembled continuous model.
#[derive(Debug, Clone)]
pub struct PlantModel {
    /// Inputs [`input`], outputs [`output`].
    pub sys: StateSpace,
    /// State range of the mechanics: `x1..x4` then `v1..v4` (m, m/s).
    pub mechanics: Range<usize>,
}

/// Input names of [`mechanics`], with units.
pub const MECHANICS_INPUTS: [&str; 4] = [
    "motor_force_n",
    "cutting_force_n",
    "base_m",
    "base_velocity_m_s",
];
/// Output names of [`mechanics`], with units.
pub const MECHANICS_OUTPUTS: [&str; 8] = [
    "tool_m",
    "gap_m",
    "accel_m2_m_s2",
    "x1_m",
    "x2_m",
    "x3_m",
    "x4_m",
    "coil_velocity_m_s",
];

/// The mechanics alone: inputs `[F_motor, F_cut, xg, ẋg]` (N, N, m, m/s), outputs
/// `[x1 − xg, x2 − xg, ẍ2, x1, x2, x3, x4, v2 − v3]` (m, m, m/s², m…, m/s); states
/// `x1..x4, v1..v4`.
pub fn mechanics(p: &StageParams) -> StateSpace {
    let m = [p.m1_kg, p.m2_kg, p.m3_kg, p.m4_kg];
    // (body i, body j or None for the base, stiffness, damping)
    let links: [(usize, Option<usize>, f64, f64); 5] = [
        (0, Some(1), p.k1_n_per_m, p.c1_n_s_per_m),
        (1, Some(2), p.k2_n_per_m, p.c2_n_s_per_m),
        (2, None, p.k3_n_per_m, p.c3_n_s_per_m),
        (1, Some(3), p.k4_n_per_m, p.c4_n_s_per_m),
        (1, None, p.k5_n_per_m, p.c5_n_s_per_m),
    ];
    let mut k = DMatrix::<f64>::zeros(4, 4);
    let mut c = DMatrix::<f64>::zeros(4, 4);
    let mut base = DMatrix::<f64>::zeros(4, 2); // force per unit xg, per unit ẋg
    for (i, j, kk, cc) in links {
        k[(i, i)] += kk;
        c[(i, i)] += cc;
        match j {
            Some(j) => {
                k[(j, j)] += kk;
                c[(j, j)] += cc;
                k[(i, j)] -= kk;
                k[(j, i)] -= kk;
                c[(i, j)] -= cc;
                c[(j, i)] -= cc;
            }
            None => {
                base[(i, 0)] += kk;
                base[(i, 1)] += cc;
            }
        }
    }
    let mut a = DMatrix::zeros(8, 8);
    let mut b = DMatrix::zeros(8, 4);
    for i in 0..4 {
        a[(i, 4 + i)] = 1.0;
        for j in 0..4 {
            a[(4 + i, j)] = -k[(i, j)] / m[i];
            a[(4 + i, 4 + j)] = -c[(i, j)] / m[i];
        }
        b[(4 + i, 2)] = base[(i, 0)] / m[i];
        b[(4 + i, 3)] = base[(i, 1)] / m[i];
    }
    b[(5, 0)] = 1.0 / m[1]; // motor force on m2
    b[(4, 1)] = 1.0 / m[0]; // cutting force on m1
    let mut cm = DMatrix::zeros(8, 8);
    let mut d = DMatrix::zeros(8, 4);
    cm[(7, 5)] = 1.0;
    cm[(7, 6)] = -1.0;
    cm[(0, 0)] = 1.0;
    d[(0, 2)] = -1.0;
    cm[(1, 1)] = 1.0;
    d[(1, 2)] = -1.0;
    cm.row_mut(2).copy_from(&a.row(5));
    d.row_mut(2).copy_from(&b.row(5));
    for i in 0..4 {
        cm[(3 + i, i)] = 1.0;
    }
    StateSpace { a, b, c: cm, d }
}

/// `k·ω²/(s² + 2ζω s + ω²)`.
fn second_order_lowpass(f_hz: f64, zeta: f64, k: f64) -> Result<StateSpace, LtiError> {
    let w = rad(f_hz);
    StateSpace::from_tf(&[k * w * w], &[1.0, 2.0 * zeta * w, w * w])
}

/// The current noise filter Wi of DESIGN.md (eq 6-7 made stable and minimum-phase), A/√Hz.
pub fn current_noise_filter(gain: f64) -> Result<StateSpace, LtiError> {
    let w = rad(7748.0);
    let eps = rad(0.1);
    let peak = StateSpace::from_tf(&[1.0, 0.1 * w, w * w], &[1.0, 0.005 * w, w * w])?;
    let low = StateSpace::from_tf(&[1.0, 200.0 * std::f64::consts::PI], &[1.0, eps])?;
    Ok(peak.series(&low)?.scaled(gain))
}

/// The base vibration filter Wg (eq 6-8 made stable) with a 2nd-order Butterworth roll-off at
/// `rolloff_hz`, so the base motion has a velocity and an acceleration; m/√Hz.
pub fn base_vibration_filter(gain: f64, rolloff_hz: f64) -> Result<StateSpace, LtiError> {
    let eps = rad(0.1);
    let wg = StateSpace::from_tf(&[1.0, 2000.0 * std::f64::consts::PI], &[1.0, eps])?;
    Ok(wg
        .series(&second_order_lowpass(rolloff_hz, SQRT_2 / 2.0, 1.0)?)?
        .scaled(gain))
}

/// Accelerometer noise fitted to Table 7-2 (15, 3.8, 1.1, 0.4 µg/√Hz at 1, 10, 100, 1000 Hz;
/// fit within 0.02 dB at those points): `K·(s + z1)(s + z2)/((s + p1)(s + p2))`, m/s²/√Hz.
pub fn accel_noise_filter(scale: f64) -> Result<StateSpace, LtiError> {
    const G: f64 = 9.80665;
    let k = 0.3855e-6 * G * scale;
    let (z1, z2, p1, p2) = (rad(3.893), rad(279.7), rad(28.85), rad(0.0536));
    let a = StateSpace::from_tf(&[1.0, z1], &[1.0, p1])?;
    let b = StateSpace::from_tf(&[1.0, z2], &[1.0, p2])?;
    Ok(a.series(&b)?.scaled(k))
}

/// The anti-aliasing stage of both converter channels: two first-order low passes at
/// `corner_hz` (unit DC gain), or a pass-through for 0.
pub fn anti_alias(corner_hz: f64) -> Result<StateSpace, LtiError> {
    if corner_hz == 0.0 {
        return Ok(StateSpace {
            a: DMatrix::zeros(0, 0),
            b: DMatrix::zeros(0, 2),
            c: DMatrix::zeros(2, 0),
            d: DMatrix::identity(2, 2),
        });
    }
    let w = rad(corner_hz);
    Ok(StateSpace {
        a: DMatrix::identity(2, 2) * -w,
        b: DMatrix::identity(2, 2) * w,
        c: DMatrix::identity(2, 2),
        d: DMatrix::zeros(2, 2),
    })
}

/// Appends the first and second derivatives of a SISO output with relative degree ≥ 2:
/// outputs `[y, ẏ, ÿ]`.
fn with_derivatives(sys: StateSpace) -> StateSpace {
    let ca = &sys.c * &sys.a;
    let c = DMatrix::from_rows(&[
        sys.c.row(0).into_owned(),
        ca.row(0).into_owned(),
        (&ca * &sys.a).row(0).into_owned(),
    ]);
    let cab = (&ca * &sys.b)[(0, 0)];
    let d = DMatrix::from_column_slice(3, 1, &[0.0, 0.0, cab]);
    StateSpace { c, d, ..sys }
}

/// `value` at `key` within the table's range, else the parameter error naming both.
pub(crate) fn check(key: &'static str, value: f64) -> Result<(), ModelError> {
    let l = limit_of(key).expect("every checked key has a limit");
    within(key, value, l.min, l.max, l.range)
}

/// `value` at `key` within `[lo, hi]` (a range narrowed by another value), else the error.
pub(crate) fn within(
    key: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    range: &str,
) -> Result<(), ModelError> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ModelError::Parameter {
            key,
            value,
            range: range.to_owned(),
        })
    }
}

impl PlantModel {
    /// Assembles the model of `p`; rejects unphysical parameters with the key and range.
    pub fn new(p: &PlantParams) -> Result<Self, ModelError> {
        let s = &p.stage;
        let a = &p.actuator;
        let (c, acc, n) = (&a.coil, &p.accel, &p.noise);
        for (key, value) in [
            ("stage.m1_kg", s.m1_kg),
            ("stage.m2_kg", s.m2_kg),
            ("stage.m3_kg", s.m3_kg),
            ("stage.m4_kg", s.m4_kg),
            ("stage.k1_n_per_m", s.k1_n_per_m),
            ("stage.k2_n_per_m", s.k2_n_per_m),
            ("stage.k3_n_per_m", s.k3_n_per_m),
            ("stage.k4_n_per_m", s.k4_n_per_m),
            ("stage.k5_n_per_m", s.k5_n_per_m),
            ("stage.c1_n_s_per_m", s.c1_n_s_per_m),
            ("stage.c2_n_s_per_m", s.c2_n_s_per_m),
            ("stage.c3_n_s_per_m", s.c3_n_s_per_m),
            ("stage.c4_n_s_per_m", s.c4_n_s_per_m),
            ("stage.c5_n_s_per_m", s.c5_n_s_per_m),
            ("actuator.kt_n_per_a", a.kt_n_per_a),
            ("actuator.current_bandwidth_hz", a.current_bandwidth_hz),
            ("actuator.current_damping", a.current_damping),
            ("actuator.current_gain_a_per_v", a.current_gain_a_per_v),
            ("capa.bandwidth_hz", p.capa.bandwidth_hz),
            ("capa.sensitivity_v_per_m", p.capa.sensitivity_v_per_m),
            ("accel.sensitivity_v_per_m_s2", acc.sensitivity_v_per_m_s2),
            (
                "accel.highpass_time_constant_s",
                acc.highpass_time_constant_s,
            ),
            ("accel.resonance_hz", acc.resonance_hz),
            ("accel.resonance_q", acc.resonance_q),
            ("accel.lowpass_hz", acc.lowpass_hz),
            ("noise.sensor_v_per_rt_hz", n.sensor_v_per_rt_hz),
            ("noise.current_a_per_rt_hz", n.current_a_per_rt_hz),
            ("noise.base_m_per_rt_hz", n.base_m_per_rt_hz),
            ("noise.base_rolloff_hz", n.base_rolloff_hz),
            ("noise.accel_scale", n.accel_scale),
            // Every current-loop setting is checked, whichever model is selected: a file
            // valid today stays valid when the model is switched.
            ("actuator.coil.resistance_ohm", c.resistance_ohm),
            ("actuator.coil.sense_resistance_ohm", c.sense_resistance_ohm),
            ("actuator.coil.inductance_h", c.inductance_h),
            ("actuator.coil.bus_v", c.bus_v),
            ("actuator.coil.peak_a", c.peak_a),
            ("actuator.coil.loop_bandwidth_hz", c.loop_bandwidth_hz),
            ("actuator.coil.substeps", c.substeps as f64),
        ] {
            check(key, value)?;
        }
        let aa = p.adc.anti_alias_hz;
        if aa != 0.0 {
            let range = limit_of("adc.anti_alias_hz").map_or("", |l| l.range);
            within("adc.anti_alias_hz", aa, 1.0, 1e8, range)?;
        }
        for (key, value, lo, hi, range) in p.modes.ranges() {
            within(key, value, lo, hi, range)?;
        }
        let ideal = second_order_lowpass(
            a.current_bandwidth_hz,
            a.current_damping,
            a.current_gain_a_per_v,
        )?;
        // The `coil` model integrates the electrical loop outside; here the input is the current.
        let current = match a.model {
            CurrentLoopModel::Ideal => ideal,
            CurrentLoopModel::Coil => {
                NamedBlock::gain(
                    "current",
                    DMatrix::from_element(1, 1, 1.0),
                    &["v_cmd_in"],
                    &["coil_current_a"],
                )
                .sys
            }
        };
        let capa = second_order_lowpass(
            p.capa.bandwidth_hz,
            SQRT_2 / 2.0,
            p.capa.sensitivity_v_per_m,
        )?;
        let w_r = rad(acc.resonance_hz);
        let resonance =
            StateSpace::from_tf(&[w_r * w_r], &[1.0, w_r / acc.resonance_q, w_r * w_r])?;
        let highpass =
            StateSpace::from_tf(&[1.0, 0.0], &[1.0, 1.0 / acc.highpass_time_constant_s])?;
        let conditioning =
            second_order_lowpass(acc.lowpass_hz, SQRT_2 / 2.0, acc.sensitivity_v_per_m_s2)?;
        let accel_chain = resonance.series(&highpass)?.series(&conditioning)?;
        let gain = |on: bool, g: f64| if on { g } else { 0.0 };
        let kt = a.kt_n_per_a;

        let net = Interconnect::new(&["v_cmd", "f_cut", "w_i", "w_g", "w_a"])
            .block(NamedBlock::new(
                "mech",
                mechanics(s),
                &["f_motor_in", "f_cut_in", "xg_in", "vg_in"],
                &[
                    "tool_m",
                    "gap_m",
                    "accel_m2",
                    "x1",
                    "x2",
                    "x3",
                    "x4",
                    "coil_velocity",
                ],
            ))
            .block(NamedBlock::new(
                "current",
                current,
                &["v_cmd_in"],
                &["coil_current_a"],
            ))
            .block(NamedBlock::new(
                "wi",
                current_noise_filter(gain(n.current, n.current_a_per_rt_hz))?,
                &["w_i_in"],
                &["current_noise_a"],
            ))
            .block(NamedBlock::gain(
                "motor",
                DMatrix::from_row_slice(1, 2, &[kt, kt]),
                &["i_coil_in", "i_noise_in"],
                &["motor_force_n"],
            ))
            .block(NamedBlock::new(
                "wg",
                with_derivatives(base_vibration_filter(
                    gain(n.base, n.base_m_per_rt_hz),
                    n.base_rolloff_hz,
                )?),
                &["w_g_in"],
                &["base_m", "base_v", "base_a"],
            ))
            .block(NamedBlock::new("capa", capa, &["gap_in"], &["sensor_out"]))
            .block(NamedBlock::new(
                "wacc",
                accel_noise_filter(gain(n.accel, n.accel_scale))?,
                &["w_a_in"],
                &["accel_noise"],
            ))
            .block(NamedBlock::new(
                "accel",
                accel_chain,
                &["accel_in"],
                &["accel_out"],
            ))
            .block(NamedBlock::new(
                "aa",
                anti_alias(aa)?,
                &["aa_gap_in", "aa_acc_in"],
                &["sensor_v", "accel_v"],
            ))
            .wire("aa_acc_in", "accel_out", 1.0)
            .wire("f_cut_in", "f_cut", 1.0)
            .wire("xg_in", "base_m", 1.0)
            .wire("vg_in", "base_v", 1.0)
            .wire("v_cmd_in", "v_cmd", 1.0)
            .wire("w_i_in", "w_i", 1.0)
            .wire("i_coil_in", "coil_current_a", 1.0)
            .wire("i_noise_in", "current_noise_a", 1.0)
            .wire("w_g_in", "w_g", 1.0)
            .wire("gap_in", "gap_m", 1.0)
            .wire("w_a_in", "w_a", 1.0)
            .wire("accel_in", "accel_m2", 1.0)
            .wire("accel_in", "accel_noise", 1.0)
            .wire(
                "accel_in",
                "base_a",
                if acc.base_difference { -1.0 } else { 0.0 },
            );
        // Extra modes sit between the motor and the mechanics, and between the sensor and the
        // anti-alias filter; a site without any is a plain wire.
        let sites = [
            (
                ModeSite::Force,
                "modes_force",
                "f_motor_in",
                "motor_force_n",
            ),
            (ModeSite::Sensor, "modes_sensor", "aa_gap_in", "sensor_out"),
        ];
        let mut net = net;
        for (site, name, to, from) in sites {
            net = match p.modes.state_space(site)? {
                Some(chain) => {
                    let (input, out) = (format!("{name}_in"), format!("{name}_out"));
                    net.block(NamedBlock::new(name, chain, &[&input], &[&out]))
                        .wire(&input, from, 1.0)
                        .wire(to, &out, 1.0)
                }
                None => net.wire(to, from, 1.0),
            };
        }
        let connected = net.build(&output::NAMES)?;
        Ok(PlantModel {
            sys: connected.sys,
            mechanics: connected.states["mech"].clone(),
        })
    }
}
