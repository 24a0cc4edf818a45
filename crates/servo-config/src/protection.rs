//! The `[protection]` table: machine-protection limits and the safe state a trip takes the
//! loop to (what the runtime checks every tick, as LinuxCNC trips on following error).

use crate::check::{Allowed, Invalid};

/// What the DAC does after a trip.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(rename_all = "kebab-case"))]
pub enum SafeState {
    /// 0 V: zero current, the flexure springs back to its rest position — which may be
    /// toward the part.
    #[default]
    Zero,
    /// Hold the last command before the trip (the tool stays where it was driven). Holding a
    /// saturated command keeps driving the stage (10 V ≈ 1.7 mm static on the prototype): pair
    /// it with limits that trip before the command saturates.
    Hold,
    /// Ramp the command from its last value to the static command of `retract_m` at
    /// `retract_speed_m_per_s`, then hold it: a bounded move to a position chosen away from
    /// the part, open loop (the sensor may be what failed).
    Retract,
}

impl SafeState {
    /// The name used in configs, recordings and messages.
    pub fn name(self) -> &'static str {
        match self {
            SafeState::Zero => "zero",
            SafeState::Hold => "hold",
            SafeState::Retract => "retract",
        }
    }
}

/// Machine-protection limits. Every limit is checked on every tick; the first one exceeded
/// trips the loop to `safe_state`, which it keeps for `after_trip_s` before the run ends
/// (recorded, exit code 5). A non-finite controller output or a latched block fault (NaN
/// reading, lost spindle lock) always trips.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(deny_unknown_fields, default))]
pub struct ProtectionConfig {
    /// Protection on (false: limits are not checked; faults still drive 0 V).
    pub enabled: bool,
    /// Trip when |reference − measured| exceeds this, in m (20 µm, 80 % of the gap sensor's
    /// ±25.6 µm: a step reference larger than this trips at once); 0 = off.
    pub following_error_m: f64,
    /// Trip when |measured position| exceeds this, in m; unset: when a gap conversion clips at
    /// the ADC range (the loop is blind beyond it; that always trips).
    pub position_limit_m: Option<f64>,
    /// Trip when the command stays at its limit (or the DAC clips) for longer than this, in s
    /// (10 ms: the amplifier and coil at full power, the loop no longer in control); 0 = off.
    pub saturation_s: f64,
    /// The state a trip takes the DAC to.
    pub safe_state: SafeState,
    /// Where the `retract` safe state takes the tool, in m from the flexure's rest position
    /// (−5 µm; which sign is away from the part depends on the machine). Reached open loop
    /// through the stage's static gain (the plant's DC compliance; 0.167 mm/V on the thesis
    /// prototype), so the command must stay within ±controller.limit_v.
    pub retract_m: f64,
    /// Speed of the `retract` ramp, in m/s (5 mm/s: the fastest motion of the thesis's
    /// sinusoidal grid; 1 ms for 5 µm).
    pub retract_speed_m_per_s: f64,
    /// How long the loop keeps the safe state after a trip before the run ends, in s
    /// (recorded, so the aftermath is in the file).
    pub after_trip_s: f64,
}

impl Default for ProtectionConfig {
    fn default() -> Self {
        ProtectionConfig {
            enabled: true,
            following_error_m: 20e-6,
            position_limit_m: None,
            saturation_s: 0.01,
            safe_state: SafeState::Zero,
            retract_m: -5e-6,
            retract_speed_m_per_s: 5e-3,
            after_trip_s: 0.005,
        }
    }
}

impl ProtectionConfig {
    /// Checks every value against its allowed range (keys relative to `[protection]`;
    /// `limit_v`: the controller's output limit in V; `dc_gain_m_per_v`: the stage's static
    /// tool displacement per DAC volt).
    pub fn check(&self, limit_v: f64, dc_gain_m_per_v: f64) -> Result<(), Invalid> {
        let p = self;
        let invalid = |key, value, allowed| Err(Invalid::new("protection", key, value, allowed));
        if !(p.following_error_m >= 0.0 && p.following_error_m <= 1e-3) {
            return invalid(
                "following_error_m",
                p.following_error_m,
                Allowed::Text("0 (off) or (0, 1e-3] m"),
            );
        }
        if let Some(x) = p.position_limit_m {
            if !(x > 0.0 && x <= 1e-3) {
                return invalid("position_limit_m", x, Allowed::Text("(0, 1e-3] m"));
            }
        }
        if !(p.saturation_s >= 0.0 && p.saturation_s <= 10.0) {
            return invalid(
                "saturation_s",
                p.saturation_s,
                Allowed::Text("0 (off) or (0, 10] s"),
            );
        }
        let reach = (limit_v * libm::fabs(dc_gain_m_per_v)).min(1e-3);
        if !(p.retract_m.is_finite() && libm::fabs(p.retract_m) <= reach) {
            return invalid(
                "retract_m",
                p.retract_m,
                Allowed::PlusMinus {
                    reach,
                    unit: "m (controller.limit_v through the stage's static gain, at most 1 mm)",
                },
            );
        }
        if !(p.retract_speed_m_per_s > 0.0 && p.retract_speed_m_per_s <= 1.0) {
            return invalid(
                "retract_speed_m_per_s",
                p.retract_speed_m_per_s,
                Allowed::Text("(0, 1] m/s"),
            );
        }
        if !(p.after_trip_s >= 0.0 && p.after_trip_s <= 1.0) {
            return invalid(
                "after_trip_s",
                p.after_trip_s,
                Allowed::between(0.0, 1.0, "s"),
            );
        }
        Ok(())
    }
}
