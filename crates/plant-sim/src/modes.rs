//! Resonances the four-mass model does not contain — a sensor mount, a part of the frame, a
//! coil former — as second-order factors with unit gain at DC,
//! `N(s) = (ωp²/ωz²)·(s² + 2ζz·ωz·s + ωz²)/(s² + 2ζp·ωp·s + ωp²)`, placed on the gap reading
//! (a mode between the gap and its reading, which the tool does not feel) or on the motor force
//! (a mode of the stage, which every output sees). `[[plant.modes]]` in a plant file; what
//! `servo identify` writes when it finds one and what the practice stage hides.

use lti::{LtiError, StateSpace};
use num_complex::Complex64;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// `2π·f`.
fn rad(f_hz: f64) -> f64 {
    2.0 * std::f64::consts::PI * f_hz
}

/// Most extra modes a plant carries.
pub const MAX_MODES: usize = 4;

/// Where an extra mode acts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(rename_all = "kebab-case")]
pub enum ModeSite {
    /// On the capacitive reading (after the sensor, before the anti-alias filter): the reading
    /// moves, the tool does not (a sensor mount).
    #[default]
    Sensor,
    /// On the motor force (before the mechanics): the tool, the gap and the accelerometer all
    /// see it (a mode of the stage or the actuator).
    Force,
}

/// One extra mode: a pole pair and a zero pair, unit gain at DC.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ExtraMode {
    /// Where it acts (`sensor` or `force`; default `sensor`).
    #[serde(default)]
    pub at: ModeSite,
    /// Pole pair frequency in Hz, [1, 1e8].
    pub hz: f64,
    /// Pole pair damping ratio, [1e-4, 10].
    pub zeta: f64,
    /// Zero pair frequency in Hz, [1, 1e8] (equal to `hz` for a peak of `zero_zeta/zeta`
    /// without a change of gain above it).
    pub zero_hz: f64,
    /// Zero pair damping ratio, [0, 10] (0: a notch that reaches zero).
    pub zero_zeta: f64,
}

impl ExtraMode {
    /// `N(j·2π·f_hz)`, dimensionless.
    pub fn response(&self, f_hz: f64) -> Complex64 {
        let s = Complex64::new(0.0, rad(f_hz));
        let (wp, wz) = (rad(self.hz), rad(self.zero_hz));
        (s * s + 2.0 * self.zero_zeta * wz * s + wz * wz)
            / (s * s + 2.0 * self.zeta * wp * s + wp * wp)
            * (wp * wp / (wz * wz))
    }

    /// The factor as a state space (one input, one output, two states).
    pub fn state_space(&self) -> Result<StateSpace, LtiError> {
        let (wp, wz) = (rad(self.hz), rad(self.zero_hz));
        let k = wp * wp / (wz * wz);
        StateSpace::from_tf(
            &[k, k * 2.0 * self.zero_zeta * wz, k * wz * wz],
            &[1.0, 2.0 * self.zeta * wp, wp * wp],
        )
    }

    /// The mode's largest effect on the response near its pole, dB (`|N|` at the pole
    /// frequency).
    pub fn peak_db(&self) -> f64 {
        20.0 * libm::log10(self.response(self.hz).norm())
    }
}

/// The extra modes of a plant (at most [`MAX_MODES`]), in the order the file gives them; a
/// TOML array of tables, `[[plant.modes]]`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ExtraModes {
    modes: [Option<ExtraMode>; MAX_MODES],
}

impl ExtraModes {
    /// The modes of `list`; `None` when it holds more than [`MAX_MODES`].
    pub fn new(list: &[ExtraMode]) -> Option<Self> {
        let mut modes = [None; MAX_MODES];
        for (slot, m) in modes.iter_mut().zip(list) {
            *slot = Some(*m);
        }
        (list.len() <= MAX_MODES).then_some(ExtraModes { modes })
    }

    /// These modes and then `more`, as many as fit in [`MAX_MODES`] (the rest left out).
    pub fn with<'a>(&self, more: impl IntoIterator<Item = &'a ExtraMode>) -> ExtraModes {
        let mut out = *self;
        let free = out.modes.iter_mut().filter(|m| m.is_none());
        for (slot, m) in free.zip(more) {
            *slot = Some(*m);
        }
        out
    }

    /// The modes, in order.
    pub fn iter(&self) -> impl Iterator<Item = &ExtraMode> {
        self.modes.iter().flatten()
    }

    /// Whether there are none (the four-mass model alone).
    pub fn is_empty(&self) -> bool {
        self.modes[0].is_none()
    }

    /// The product of the modes at `site`, `∏ N(j·2π·f_hz)` (1 with none).
    pub fn response(&self, site: ModeSite, f_hz: f64) -> Complex64 {
        self.iter()
            .filter(|m| m.at == site)
            .map(|m| m.response(f_hz))
            .product()
    }

    /// The modes at `site` in series, `None` with none.
    pub(crate) fn state_space(&self, site: ModeSite) -> Result<Option<StateSpace>, LtiError> {
        let mut chain: Option<StateSpace> = None;
        for m in self.iter().filter(|m| m.at == site) {
            let n = m.state_space()?;
            chain = Some(match chain {
                Some(c) => c.series(&n)?,
                None => n,
            });
        }
        Ok(chain)
    }

    /// Every value with its key (`modes[i].key`), allowed range and the range as text.
    pub(crate) fn ranges(&self) -> Vec<(&'static str, f64, f64, f64, &'static str)> {
        const KEYS: [[&str; 4]; MAX_MODES] = [
            [
                "modes[0].hz",
                "modes[0].zeta",
                "modes[0].zero_hz",
                "modes[0].zero_zeta",
            ],
            [
                "modes[1].hz",
                "modes[1].zeta",
                "modes[1].zero_hz",
                "modes[1].zero_zeta",
            ],
            [
                "modes[2].hz",
                "modes[2].zeta",
                "modes[2].zero_hz",
                "modes[2].zero_zeta",
            ],
            [
                "modes[3].hz",
                "modes[3].zeta",
                "modes[3].zero_hz",
                "modes[3].zero_zeta",
            ],
        ];
        self.iter()
            .zip(KEYS)
            .flat_map(|(m, [hz, zeta, zero_hz, zero_zeta])| {
                [
                    (hz, m.hz, 1.0, 1e8, "[1, 1e8] Hz"),
                    (zeta, m.zeta, 1e-4, 10.0, "[1e-4, 10]"),
                    (zero_hz, m.zero_hz, 1.0, 1e8, "[1, 1e8] Hz"),
                    (zero_zeta, m.zero_zeta, 0.0, 10.0, "[0, 10]"),
                ]
            })
            .collect()
    }
}

impl Serialize for ExtraModes {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter())
    }
}

impl<'de> Deserialize<'de> for ExtraModes {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let list = Vec::<ExtraMode>::deserialize(d)?;
        ExtraModes::new(&list).ok_or_else(|| {
            serde::de::Error::custom(format!(
                "{} extra modes; a plant carries at most {MAX_MODES}",
                list.len()
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mode_is_unity_at_dc_and_its_state_space_agrees_with_its_factor() {
        let m = ExtraMode {
            at: ModeSite::Sensor,
            hz: 1_600.0,
            zeta: 0.01,
            zero_hz: 1_700.0,
            zero_zeta: 0.03,
        };
        assert!((m.response(0.0) - 1.0).norm() < 1e-15);
        // Equal pole and zero frequencies peak at ζz/ζp (here about 3, +9.5 dB).
        let peak = ExtraMode {
            zero_hz: 1_600.0,
            ..m
        };
        assert!((peak.response(1_600.0).norm() - 3.0).abs() < 1e-12);
        let ss = m.state_space().unwrap();
        for f in [10.0, 1_550.0, 1_600.0, 1_700.0, 20_000.0] {
            let h = ss.freq_response(rad(f)).unwrap()[(0, 0)];
            assert!(
                (h - m.response(f)).norm() < 1e-9 * m.response(f).norm(),
                "{f} Hz"
            );
        }
    }

    #[test]
    fn more_modes_than_the_capacity_are_refused() {
        let m = ExtraMode {
            at: ModeSite::Force,
            hz: 1e3,
            zeta: 0.1,
            zero_hz: 1e3,
            zero_zeta: 0.1,
        };
        assert!(ExtraModes::new(&[m; MAX_MODES]).is_some());
        assert!(ExtraModes::new(&[m; MAX_MODES + 1]).is_none());
        // Appending keeps what fits.
        let three = ExtraModes::new(&[m; 3]).unwrap();
        assert_eq!(three.with(&[m; 3]).iter().count(), MAX_MODES);
    }
}
