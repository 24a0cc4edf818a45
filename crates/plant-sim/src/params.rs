//! Parameters of the simulated stage, in SI units; every default is the thesis prototype
//! (DESIGN.md, "The plant"; ★ marks values the thesis does not identify — our documented choice).

use crate::modes::ExtraModes;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// The four-mass flexure stage (thesis Fig 5-4, Appendix C; equations in DESIGN.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct StageParams {
    /// Tool-tip mass m1 in kg (★ 0.004; m1 + m2 = 0.074 kg, Table 5-2).
    pub m1_kg: f64,
    /// Coil and sensor carrier mass m2 in kg (0.070).
    pub m2_kg: f64,
    /// X-carriage mass m3 in kg (★ 1.5).
    pub m3_kg: f64,
    /// Parasitic mass m4 on m2 in kg (0.008, Table 5-2).
    pub m4_kg: f64,
    /// Tool shank stiffness k1 in N/m (★ 2.16e7: tool mode ≈ 11.7 kHz, §5.7.4).
    pub k1_n_per_m: f64,
    /// Tool shank damping c1 in N·s/m (★ 11.8).
    pub c1_n_s_per_m: f64,
    /// Flexure bearing stiffness k2 in N/m (21965, Table 5-2).
    pub k2_n_per_m: f64,
    /// Flexure bearing damping c2 in N·s/m (2.28, Table 5-2).
    pub c2_n_s_per_m: f64,
    /// Carriage-to-base stiffness k3 in N/m (★ 5e7).
    pub k3_n_per_m: f64,
    /// Carriage-to-base damping c3 in N·s/m (★ 866).
    pub c3_n_s_per_m: f64,
    /// Parasitic mode stiffness k4 in N/m (56285, Table 5-2).
    pub k4_n_per_m: f64,
    /// Parasitic mode damping c4 in N·s/m (6.18, Table 5-2).
    pub c4_n_s_per_m: f64,
    /// Motor magnetic stiffness k5 in N/m (0, §5.4).
    pub k5_n_per_m: f64,
    /// Motor eddy-current damping c5 in N·s/m (0, §5.4).
    pub c5_n_s_per_m: f64,
}

impl StageParams {
    /// The prototype as identified (Table 5-2): m1 + m2 = 0.074 kg.
    pub const THESIS: StageParams = StageParams {
        m1_kg: 0.004,
        m2_kg: 0.070,
        m3_kg: 1.5,
        m4_kg: 0.008,
        k1_n_per_m: 2.16e7,
        c1_n_s_per_m: 11.8,
        k2_n_per_m: 21965.0,
        c2_n_s_per_m: 2.28,
        k3_n_per_m: 5e7,
        c3_n_s_per_m: 866.0,
        k4_n_per_m: 56285.0,
        c4_n_s_per_m: 6.18,
        k5_n_per_m: 0.0,
        c5_n_s_per_m: 0.0,
    };

    /// The heavy variant of §5.7.3: 0.100 kg added to m2 (0.174 kg moving in total).
    pub const THESIS_HEAVY: StageParams = StageParams {
        m2_kg: 0.170,
        ..StageParams::THESIS
    };

    /// Mass carried by the flexure, m1 + m2 + m4, in kg (the thesis quotes m1 + m2).
    pub fn suspended_mass_kg(&self) -> f64 {
        self.m1_kg + self.m2_kg + self.m4_kg
    }
}

impl Default for StageParams {
    fn default() -> Self {
        StageParams::THESIS
    }
}

/// Which current-loop model drives the coil.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "kebab-case")]
pub enum CurrentLoopModel {
    /// Linear second-order closed loop of eq 5-9 (exact discretisation).
    #[default]
    Ideal,
    /// R-L coil driven by the analog PI current controller of §4.6.3 through a linear power
    /// amplifier with bus-voltage and peak-current limits (nonlinear: sub-stepped).
    Coil,
}

/// The coil circuit and analog current controller of §4.6.3–4.6.4 (used by
/// [`CurrentLoopModel::Coil`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct CoilParams {
    /// Coil resistance in Ω (0.55, §4.6.4).
    pub resistance_ohm: f64,
    /// Current-sense resistor in series in Ω (2, §4.6.4).
    pub sense_resistance_ohm: f64,
    /// Coil inductance in H (0.23 mH, §4.6.4).
    pub inductance_h: f64,
    /// Amplifier supply ±`bus_v` in V (36, §4.6.4).
    pub bus_v: f64,
    /// Peak coil current in A; the current reference is clamped to ±this (20, Table 4-1).
    pub peak_a: f64,
    /// Crossover of the PI current loop in Hz; the integral corner sits at the coil pole
    /// `R/L` (§4.6.3), so the loop is first order at this bandwidth (400 kHz, eq 5-9).
    pub loop_bandwidth_hz: f64,
    /// Sub-steps per servo tick for the nonlinear electrical ODE (RK4), split at the delay.
    pub substeps: u32,
}

impl Default for CoilParams {
    fn default() -> Self {
        CoilParams {
            resistance_ohm: 0.55,
            sense_resistance_ohm: 2.0,
            inductance_h: 0.23e-3,
            bus_v: 36.0,
            peak_a: 20.0,
            loop_bandwidth_hz: 400e3,
            substeps: 32,
        }
    }
}

/// Flat voice-coil motor and its closed current loop (eq 5-9).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct ActuatorParams {
    /// Current-loop model (`ideal` eq 5-9, or `coil` R-L + PI with saturation).
    pub model: CurrentLoopModel,
    /// Coil and analog controller, for the `coil` model.
    pub coil: CoilParams,
    /// Force constant K_T in N/A (3.6658, §5.5.1).
    pub kt_n_per_a: f64,
    /// Current-loop bandwidth ω_I/2π in Hz (400 kHz, eq 5-9).
    pub current_bandwidth_hz: f64,
    /// Current-loop damping ratio ζ (0.707).
    pub current_damping: f64,
    /// Transconductance at DC in A/V (1, §4.6.4).
    pub current_gain_a_per_v: f64,
}

impl Default for ActuatorParams {
    fn default() -> Self {
        ActuatorParams {
            model: CurrentLoopModel::Ideal,
            coil: CoilParams::default(),
            kt_n_per_a: 3.6658,
            current_bandwidth_hz: 400e3,
            current_damping: 0.707,
            current_gain_a_per_v: 1.0,
        }
    }
}

/// Capacitive displacement sensor (eq 5-8, printed with a `2ω` typo: a Butterworth has `√2ω`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct CapaSensorParams {
    /// −3 dB bandwidth in Hz (★ 15 kHz).
    pub bandwidth_hz: f64,
    /// Sensitivity S_capa in V/m (★ 0.16 V/µm = 1.6e5 V/m: 50 µm → ±4 V, §3.5).
    pub sensitivity_v_per_m: f64,
}

impl Default for CapaSensorParams {
    fn default() -> Self {
        CapaSensorParams {
            bandwidth_hz: 15e3,
            sensitivity_v_per_m: 1.6e5,
        }
    }
}

/// Accelerometer on m2 and its conditioning (Table 7-2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct AccelerometerParams {
    /// Sensitivity in V/(m/s²) (1000 mV/g).
    pub sensitivity_v_per_m_s2: f64,
    /// Discharge time constant of the high-pass in s (0.7–2 s; 1 s here).
    pub highpass_time_constant_s: f64,
    /// Mounted resonance in Hz (≥ 20 kHz; ★ 25 kHz).
    pub resonance_hz: f64,
    /// Quality factor of the mounted resonance (★ 20).
    pub resonance_q: f64,
    /// Conditioning low-pass (2nd-order Butterworth) corner in Hz (10 kHz).
    pub lowpass_hz: f64,
    /// Measure `ẍ2 − ẍg` with a second accelerometer on the base (§7.5.1).
    pub base_difference: bool,
}

impl Default for AccelerometerParams {
    fn default() -> Self {
        AccelerometerParams {
            sensitivity_v_per_m_s2: 1.0 / 9.80665,
            highpass_time_constant_s: 1.0,
            resonance_hz: 25e3,
            resonance_q: 20.0,
            lowpass_hz: 10e3,
            base_difference: false,
        }
    }
}

/// Analog-to-digital converter (§4.5.1, §4.4.3), shared by the gap and accelerometer channels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct AdcParams {
    /// Resolution in bits (16).
    pub bits: u32,
    /// Full scale ±`range_v` in V (4.096).
    pub range_v: f64,
    /// Conversions averaged per servo tick (4).
    pub oversampling: u32,
    /// Conversion rate in Hz (1 MHz); the last conversion is at the tick.
    pub conversion_rate_hz: f64,
    /// Corner of a first-order anti-aliasing stage before the converter on both channels, in
    /// Hz; 0 = none (default: §4.4.4 and §4.5.2 describe a first-order stage but print no
    /// corner; the sensor's own 15 kHz filter already band-limits the gap channel).
    pub anti_alias_hz: f64,
}

impl Default for AdcParams {
    fn default() -> Self {
        AdcParams {
            bits: 16,
            range_v: 4.096,
            oversampling: 4,
            conversion_rate_hz: 1e6,
            anti_alias_hz: 0.0,
        }
    }
}

/// Digital-to-analog converter (§4.4.1). Its 1 µs settling is part of the transport delay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct DacParams {
    /// Resolution in bits (18).
    pub bits: u32,
    /// Full scale ±`range_v` in V (10).
    pub range_v: f64,
}

impl Default for DacParams {
    fn default() -> Self {
        DacParams {
            bits: 18,
            range_v: 10.0,
        }
    }
}

/// Stochastic disturbances (thesis eq 6-6..6-8, DESIGN.md; gains calibrated, see README).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct NoiseParams {
    /// Sensor noise one-sided ASD in V/√Hz, flat at the sensor electronics and band-limited by
    /// its output filter (`capa.bandwidth_hz`, the Butterworth of eq 5-8), so each conversion
    /// sees `Ws²·π f_c/(2√2)` whatever the servo rate (calibrated 9.708e-7; thesis eq 6-6:
    /// 1.36e-6).
    pub sensor_v_per_rt_hz: f64,
    /// Current noise gain of Wi in A/√Hz (calibrated 3.225e-7; thesis eq 6-7: 1.64e-7).
    pub current_a_per_rt_hz: f64,
    /// Base vibration gain of Wg in m/√Hz (calibrated 4.159e-13; thesis eq 6-8: 2.83e-9).
    pub base_m_per_rt_hz: f64,
    /// Corner of the 2nd-order roll-off that makes the base motion differentiable, in Hz
    /// (15 kHz: the thesis fitted its spectra only up to the sensor bandwidth, §6.3.2).
    pub base_rolloff_hz: f64,
    /// Scale of the accelerometer noise fitted to Table 7-2 (1 = datasheet).
    pub accel_scale: f64,
    /// Sensor noise on.
    pub sensor: bool,
    /// Current noise on.
    pub current: bool,
    /// Base vibration on.
    pub base: bool,
    /// Accelerometer noise on.
    pub accel: bool,
}

impl Default for NoiseParams {
    fn default() -> Self {
        NoiseParams {
            // Calibrated (plant-sim README; `cargo run --release -p studies --example
            // calibrate`): 0.83 nm following and 0.23 nm true error at 468 Hz on the 0.174 kg
            // stage (§5.7.4), base vibration 10 % of the true-error power.
            sensor_v_per_rt_hz: 9.708e-7,
            current_a_per_rt_hz: 3.225e-7,
            base_m_per_rt_hz: 4.159e-13,
            base_rolloff_hz: 15e3,
            accel_scale: 1.0,
            sensor: true,
            current: true,
            base: true,
            accel: true,
        }
    }
}

/// Servo timing (§4.4, §5.7.3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct TimingParams {
    /// Servo rate in Hz (199.6 kHz).
    pub servo_rate_hz: f64,
    /// Transport delay from the tick to the coil in s (3.159 µs, Table 4-2).
    pub delay_s: f64,
}

impl Default for TimingParams {
    fn default() -> Self {
        TimingParams {
            servo_rate_hz: 199_600.0,
            delay_s: 3.159e-6,
        }
    }
}

/// Everything the simulator needs.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct PlantParams {
    /// Mechanics.
    pub stage: StageParams,
    /// Motor and current loop.
    pub actuator: ActuatorParams,
    /// Capacitive sensor.
    pub capa: CapaSensorParams,
    /// Accelerometer.
    pub accel: AccelerometerParams,
    /// ADC.
    pub adc: AdcParams,
    /// DAC.
    pub dac: DacParams,
    /// Noise sources.
    pub noise: NoiseParams,
    /// Servo rate and delay.
    pub timing: TimingParams,
    /// Resonances the four-mass model lacks, `[[plant.modes]]` (none by default; left out of
    /// the file, and of its provenance digest, when empty).
    #[serde(skip_serializing_if = "ExtraModes::is_empty")]
    #[cfg_attr(feature = "schema", schemars(with = "Vec<crate::modes::ExtraMode>"))]
    pub modes: ExtraModes,
}

impl PlantParams {
    /// Static tool displacement per DAC volt, in m/V: the current loop's DC transconductance
    /// × K_T over the static stiffness at the coil carrier (k2 in series with k3, in parallel
    /// with k5; m1 and m4 follow m2 at DC). 0.167 mm/V on the thesis prototype.
    pub fn dc_gain_m_per_v(&self) -> f64 {
        let s = &self.stage;
        let k = s.k2_n_per_m * s.k3_n_per_m / (s.k2_n_per_m + s.k3_n_per_m) + s.k5_n_per_m;
        self.actuator.current_gain_a_per_v * self.actuator.kt_n_per_a / k
    }

    /// The thesis prototype with the 0.174 kg heavy stage (§5.7.3).
    pub fn heavy() -> Self {
        PlantParams {
            stage: StageParams::THESIS_HEAVY,
            ..Default::default()
        }
    }

    /// Servo period in s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.timing.servo_rate_hz
    }
}

/// `2π·f`.
pub(crate) fn rad(f_hz: f64) -> f64 {
    2.0 * PI * f_hz
}
