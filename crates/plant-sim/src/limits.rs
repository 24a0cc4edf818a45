//! The allowed range of every scalar plant parameter, at its `[plant]` key: what building a
//! stage checks, and what a model description (an FMU's) declares as each parameter's min and
//! max. One table, so the two cannot disagree.

/// The allowed range of one parameter: `min ≤ value ≤ max`, in the key's SI unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limit {
    /// Dotted key under `[plant]` (`stage.m1_kg`).
    pub key: &'static str,
    /// Smallest allowed value.
    pub min: f64,
    /// Largest allowed value.
    pub max: f64,
    /// The range as the error message states it, with its unit.
    pub range: &'static str,
}

const fn limit(key: &'static str, min: f64, max: f64, range: &'static str) -> Limit {
    Limit {
        key,
        min,
        max,
        range,
    }
}

const MASS: &str = "[1e-6, 1e3] kg";
const STIFFNESS: &str = "[0, 1e12] N/m";
const DAMPING: &str = "[0, 1e12] N·s/m";
const FREQUENCY: &str = "[1, 1e8] Hz";

/// Every scalar plant parameter with a range (booleans, the current-loop model and the extra
/// modes are not here: the modes check their own). Some are narrowed further by another value
/// when the stage is built: `timing.delay_s` ≤ the period, `adc.oversampling` ≤ the conversions
/// in a period, `adc.anti_alias_hz` 0 (none) or within its range.
pub const LIMITS: &[Limit] = &[
    limit("stage.m1_kg", 1e-6, 1e3, MASS),
    limit("stage.m2_kg", 1e-6, 1e3, MASS),
    limit("stage.m3_kg", 1e-6, 1e3, MASS),
    limit("stage.m4_kg", 1e-6, 1e3, MASS),
    limit("stage.k1_n_per_m", 0.0, 1e12, STIFFNESS),
    limit("stage.c1_n_s_per_m", 0.0, 1e12, DAMPING),
    limit("stage.k2_n_per_m", 0.0, 1e12, STIFFNESS),
    limit("stage.c2_n_s_per_m", 0.0, 1e12, DAMPING),
    limit("stage.k3_n_per_m", 0.0, 1e12, STIFFNESS),
    limit("stage.c3_n_s_per_m", 0.0, 1e12, DAMPING),
    limit("stage.k4_n_per_m", 0.0, 1e12, STIFFNESS),
    limit("stage.c4_n_s_per_m", 0.0, 1e12, DAMPING),
    limit("stage.k5_n_per_m", 0.0, 1e12, STIFFNESS),
    limit("stage.c5_n_s_per_m", 0.0, 1e12, DAMPING),
    limit("actuator.coil.resistance_ohm", 1e-6, 1e3, "[1e-6, 1e3] Ω"),
    limit("actuator.coil.sense_resistance_ohm", 0.0, 1e3, "[0, 1e3] Ω"),
    limit("actuator.coil.inductance_h", 1e-9, 10.0, "[1e-9, 10] H"),
    limit("actuator.coil.bus_v", 0.1, 1e4, "[0.1, 1e4] V"),
    limit("actuator.coil.peak_a", 1e-3, 1e4, "[1e-3, 1e4] A"),
    limit("actuator.coil.loop_bandwidth_hz", 1.0, 1e8, FREQUENCY),
    limit("actuator.coil.substeps", 2.0, 4096.0, "[2, 4096]"),
    limit("actuator.kt_n_per_a", 1e-6, 1e4, "[1e-6, 1e4] N/A"),
    limit("actuator.current_bandwidth_hz", 1.0, 1e8, FREQUENCY),
    limit("actuator.current_damping", 0.01, 10.0, "[0.01, 10]"),
    limit(
        "actuator.current_gain_a_per_v",
        1e-6,
        1e3,
        "[1e-6, 1e3] A/V",
    ),
    limit("capa.bandwidth_hz", 1.0, 1e8, FREQUENCY),
    limit("capa.sensitivity_v_per_m", 1.0, 1e12, "[1, 1e12] V/m"),
    limit(
        "accel.sensitivity_v_per_m_s2",
        1e-9,
        1e3,
        "[1e-9, 1e3] V/(m/s²)",
    ),
    limit("accel.highpass_time_constant_s", 1e-4, 1e4, "[1e-4, 1e4] s"),
    limit("accel.resonance_hz", 1.0, 1e8, FREQUENCY),
    limit("accel.resonance_q", 0.1, 1e4, "[0.1, 1e4]"),
    limit("accel.lowpass_hz", 1.0, 1e8, FREQUENCY),
    limit("adc.bits", 0.0, 31.0, "[0, 31] (0: ideal)"),
    limit("adc.range_v", 1e-3, 1e3, "[1e-3, 1e3] V"),
    limit("adc.oversampling", 1.0, 1e9, "[1, conversions per period]"),
    limit("adc.conversion_rate_hz", 1.0, 1e9, "[1, 1e9] Hz"),
    limit("adc.anti_alias_hz", 0.0, 1e8, "0 (none) or [1, 1e8] Hz"),
    limit("dac.bits", 0.0, 31.0, "[0, 31] (0: ideal)"),
    limit("dac.range_v", 1e-3, 1e3, "[1e-3, 1e3] V"),
    limit("noise.sensor_v_per_rt_hz", 0.0, 1.0, "[0, 1] V/√Hz"),
    limit("noise.current_a_per_rt_hz", 0.0, 1.0, "[0, 1] A/√Hz"),
    limit("noise.base_m_per_rt_hz", 0.0, 1e-3, "[0, 1e-3] m/√Hz"),
    limit("noise.base_rolloff_hz", 1.0, 1e8, FREQUENCY),
    limit("noise.accel_scale", 0.0, 1e6, "[0, 1e6]"),
    limit("timing.servo_rate_hz", 1.0, 10e6, "[1, 1e7] Hz"),
    limit("timing.delay_s", 0.0, 1.0, "[0, the servo period] s"),
];

/// The range of `key` (None: a key without one).
pub fn limit_of(key: &str) -> Option<&'static Limit> {
    LIMITS.iter().find(|l| l.key == key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PlantParams;

    /// Every limit's key names a number of the plant file, and the thesis prototype is inside
    /// every range (a typo in a key would leave a parameter unchecked).
    #[test]
    fn every_limit_names_a_plant_number_and_holds_the_prototype() {
        let plant = serde_json::to_value(PlantParams::default()).unwrap();
        for l in LIMITS {
            let pointer = format!("/{}", l.key.replace('.', "/"));
            let v = plant
                .pointer(&pointer)
                .and_then(|v| v.as_f64())
                .unwrap_or_else(|| panic!("{} is not a number of [plant]", l.key));
            assert!(
                l.min <= v && v <= l.max,
                "{} = {v} outside {}",
                l.key,
                l.range
            );
        }
    }
}
