//! What a `servo_runtime::Servo` runs: every number of the loop, in SI units, made offline (`servo
//! deploy` writes it from a run configuration after checking the loop on the plant model) and
//! checked once by [`Deployment::check`]. Plain data: no allocation, so a microcontroller build
//! can hold one in a `static`.

use crate::protection::{ProtectionConfig, SafeState};

/// Largest state-space controller order a loop runs (the thesis's full order is 27; `servo
/// synth` writes up to 29 with the loop delay): 40, or the cap a microcontroller build chose
/// with `FTS_SERVO_MAX_SS_ORDER` (1–40) at build time.
pub const MAX_SS_ORDER: usize = include!(concat!(env!("OUT_DIR"), "/max_order.rs"));

/// Sections of the largest ZPETC filter a loop runs (second-order sections).
pub const ZPETC_SECTIONS: usize = 12;

/// Most taps of an FIR feedforward filter.
pub const MAX_FIR_TAPS: usize = 128;

/// Ticks of trajectory an FIR feedforward can reach back (`taps·stride` at most this): the
/// runtime keeps this many past samples (16 KiB; 10 ms at 199.6 kHz, what a loop's response
/// around its 450 Hz mode needs).
pub const MAX_FIR_SPAN: usize = 2048;

/// Most ticks of reference preview (feedforward preview plus half the smoothing window).
pub const MAX_PREVIEW: usize = 62;

/// A whole loop: the stage's numbers the tick uses, the controller, its checked gain range,
/// the reference, the feedforward and machine protection.
#[derive(Debug, Clone, PartialEq)]
pub struct Deployment {
    /// The servo (sample) rate in Hz.
    pub servo_rate_hz: f64,
    /// The stage's numbers the tick uses (sensor scales, the static gain for a retract, the
    /// model-inverse feedforward, Kg scaling).
    pub stage: Stage,
    /// The feedback controller.
    pub controller: ControllerSpec,
    /// What the offline check of the loop found (None: not checked — gain changes and loads
    /// are refused).
    pub stability: Option<Stability>,
    /// The built-in reference generator (`servo_runtime::Servo::tick`; a host's own trajectory goes
    /// through `servo_runtime::Servo::tick_with`).
    pub reference: ReferenceSpec,
    /// The feedforward from the reference.
    pub feedforward: FeedforwardSpec,
    /// Zero-phase Hann smoothing of the previewed reference in Hz (0: off): a window of
    /// `servo_rate_hz / smoothing_hz` ticks, half of it added to the preview.
    pub smoothing_hz: f64,
    /// Machine-protection limits and the safe state.
    pub protection: ProtectionConfig,
}

/// The stage's numbers the tick uses, from the plant model the loop was made for.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(deny_unknown_fields))]
pub struct Stage {
    /// Capacitive gap sensor sensitivity in V/m (0.16 V/µm on the thesis prototype).
    pub gap_sensitivity_v_per_m: f64,
    /// Accelerometer sensitivity in V/(m/s²) (1000 mV/g).
    pub accel_sensitivity_v_per_m_s2: f64,
    /// Moving mass on the flexure (m1 + m2 + m4) in kg.
    pub suspended_mass_kg: f64,
    /// Flexure damping c2 in N·s/m.
    pub damping_n_s_per_m: f64,
    /// Flexure stiffness k2 in N/m.
    pub stiffness_n_per_m: f64,
    /// Current amplifier gain in A/V.
    pub current_gain_a_per_v: f64,
    /// Motor constant K_T in N/A.
    pub kt_n_per_a: f64,
    /// Static gain from command to gap in m/V (the plant's DC compliance × force per volt).
    pub dc_gain_m_per_v: f64,
}

/// Controller kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(rename_all = "kebab-case"))]
pub enum ControllerKind {
    /// Position PID (eq 7-8) on the capacitive sensor.
    #[default]
    Pid,
    /// PID plus acceleration feedback `− Ha(Ka·a)` (Fig 7-6).
    Accel,
    /// A discrete state-space controller from `ss_file`.
    Ss,
}

/// PID gains on sensor volts (V/V), thesis §7.5.3 by default.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(deny_unknown_fields, default))]
pub struct PidGains {
    /// Proportional gain (V/V).
    pub kp: f64,
    /// Integral gain (1/s).
    pub ki: f64,
    /// Derivative gain (s).
    pub kd: f64,
    /// Derivative filter time constant (s).
    pub tf_s: f64,
}

impl Default for PidGains {
    fn default() -> Self {
        let p = servo_core::PidConfig::THESIS_CH7;
        PidGains {
            kp: p.kp,
            ki: p.ki,
            kd: p.kd,
            tf_s: p.tf_s,
        }
    }
}

/// A discrete state-space controller `x⁺ = A x + B e`, `u = C x + D e` from the position error
/// `e = reference − measurement` in sensor volts to the command in volts, in fixed storage.
#[derive(Debug, Clone, PartialEq)]
pub struct SsMatrices {
    order: usize,
    /// `[[A, B], [C, D]]` in the top-left `(order + 1)²` corner.
    m: [[f64; MAX_SS_ORDER + 1]; MAX_SS_ORDER + 1],
}

impl SsMatrices {
    /// Order 0, every entry zero: storage for [`SsMatrices::refill`].
    pub const BLANK: SsMatrices = SsMatrices {
        order: 0,
        m: [[0.0; MAX_SS_ORDER + 1]; MAX_SS_ORDER + 1],
    };

    /// `[[A, B], [C, D]]` of order `n` from `entry(i, j)` for `i, j ∈ 0..=n`; None unless
    /// `1 ≤ n ≤` [`MAX_SS_ORDER`].
    pub fn from_fn(n: usize, entry: impl FnMut(usize, usize) -> f64) -> Option<Self> {
        let mut m = SsMatrices::BLANK;
        m.refill(n, entry).then_some(m)
    }

    /// [`SsMatrices::from_fn`] in place (no copy of the storage on the stack): false, `self`
    /// untouched, unless `1 ≤ n ≤` [`MAX_SS_ORDER`].
    pub fn refill(&mut self, n: usize, mut entry: impl FnMut(usize, usize) -> f64) -> bool {
        if n == 0 || n > MAX_SS_ORDER {
            return false;
        }
        for (i, row) in self.m.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = if i <= n && j <= n { entry(i, j) } else { 0.0 };
            }
        }
        self.order = n;
        true
    }

    /// The order n.
    pub fn order(&self) -> usize {
        self.order
    }

    /// Entry `(i, j)` of `[[A, B], [C, D]]`, `i, j ∈ 0..=n`.
    pub fn entry(&self, i: usize, j: usize) -> f64 {
        self.m[i][j]
    }
}

/// The feedback controller.
#[derive(Debug, Clone, PartialEq)]
pub struct ControllerSpec {
    /// `pid`, `accel` or `ss`.
    pub kind: ControllerKind,
    /// Position PID gains (for `pid` and `accel`).
    pub pid: PidGains,
    /// Acceleration gain Ka (V/V on accelerometer volts), for `accel`.
    pub ka: f64,
    /// Multiply the PID gains by 1/Kg (§7.4.1) so reference tracking stays unchanged.
    pub kg_scaling: bool,
    /// Corner of the acceleration shaping filter Ha in Hz; 0 = none.
    pub accel_filter_hz: f64,
    /// Order of Ha: 1 (first-order low pass) or 2 (Butterworth).
    pub accel_filter_order: u8,
    /// The matrices of an `ss` controller.
    pub ss: Option<SsMatrices>,
    /// Output limit ±V.
    pub limit_v: f64,
}

impl Default for ControllerSpec {
    fn default() -> Self {
        ControllerSpec {
            kind: ControllerKind::Pid,
            pid: PidGains::default(),
            ka: 0.0,
            kg_scaling: false,
            accel_filter_hz: 300.0,
            accel_filter_order: 1,
            ss: None,
            limit_v: 10.0,
        }
    }
}

/// What the offline check of a loop (the sampled closed loop of the plant model and the
/// controller) found: its spectral radius and the output scales between which it stays stable.
/// A gain change or a loaded controller keeps [`GAIN_MARGIN`] from both limits.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(deny_unknown_fields))]
pub struct Stability {
    /// Spectral radius of the sampled closed loop at scale 1 (< 1: stable).
    pub spectral_radius: f64,
    /// The loop is unstable at or below this output scale (0: stable down to no control).
    pub unstable_below: f64,
    /// The loop is unstable at or above this output scale (∞ is written as 1e300: not within
    /// 1000×).
    pub unstable_above: f64,
    /// What the check was made on, and this record as it made it ([`Stability::sealed`]): a
    /// loop whose numbers or record no longer match is refused when it is built.
    #[cfg_attr(feature = "std", serde(default))]
    pub sha256: Seal,
}

/// SHA-256 digests binding a [`Stability`] record to the loop it was made on: the servo rate
/// and [`Stage`] (`stage`), the controller's coefficients its kind uses (`controller`), and the
/// record itself with both (`record`). Not a signature — anyone can compute them — but an
/// edited gain, matrix entry or record, or a damaged copy, cannot carry the old check along.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(feature = "std", serde(deny_unknown_fields))]
pub struct Seal {
    /// Of `servo_rate_hz` and `[stage]` (hex in files).
    #[cfg_attr(feature = "std", serde(with = "hex32"))]
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub stage: [u8; 32],
    /// Of the controller's kind and the coefficients it uses: the PID gains (with Ka, Kg
    /// scaling and the acceleration filter for `accel`) or the state-space matrices.
    #[cfg_attr(feature = "std", serde(with = "hex32"))]
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub controller: [u8; 32],
    /// Of the two above and the record's three numbers.
    #[cfg_attr(feature = "std", serde(with = "hex32"))]
    #[cfg_attr(feature = "schema", schemars(with = "String"))]
    pub record: [u8; 32],
}

/// 32 bytes as 64 lowercase hex digits.
#[cfg(feature = "std")]
mod hex32 {
    pub fn serialize<S: serde::Serializer>(v: &[u8; 32], s: S) -> Result<S::Ok, S::Error> {
        let text: String = v.iter().map(|b| format!("{b:02x}")).collect();
        s.serialize_str(&text)
    }

    pub fn deserialize<'de, D: serde::Deserializer<'de>>(d: D) -> Result<[u8; 32], D::Error> {
        let text = <std::borrow::Cow<'de, str> as serde::Deserialize>::deserialize(d)?;
        let bad = || serde::de::Error::custom("expected 64 hex digits (a SHA-256)");
        if text.len() != 64 || !text.is_ascii() {
            return Err(bad());
        }
        let mut out = [0u8; 32];
        for (i, byte) in out.iter_mut().enumerate() {
            *byte = u8::from_str_radix(&text[2 * i..2 * i + 2], 16).map_err(|_| bad())?;
        }
        Ok(out)
    }
}

/// The gain margin every accepted change keeps, as a factor (2 = 6 dB).
pub const GAIN_MARGIN: f64 = 2.0;

impl Stability {
    /// The lowest output scale a change may set: [`GAIN_MARGIN`] above the lower limit.
    pub fn low(&self) -> f64 {
        self.unstable_below * GAIN_MARGIN
    }

    /// The highest output scale a change may set: [`GAIN_MARGIN`] below the upper limit.
    pub fn high(&self) -> f64 {
        self.unstable_above / GAIN_MARGIN
    }

    /// Whether the output scale `scale` is allowed (finite, within `low()..=high()`).
    pub fn allows(&self, scale: f64) -> bool {
        scale.is_finite() && scale >= self.low() && scale <= self.high()
    }
}

/// The built-in reference generators (m, positive away from the workpiece).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "std", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[cfg_attr(
    feature = "std",
    serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)
)]
pub enum ReferenceSpec {
    /// Hold position 0.
    #[default]
    Hold,
    /// `amplitude_m · sin(2π·frequency_hz·t)`.
    Sine {
        /// Amplitude in m.
        amplitude_m: f64,
        /// Frequency in Hz.
        frequency_hz: f64,
    },
    /// A step of `amplitude_m` at `at_s`.
    Step {
        /// Step height in m.
        amplitude_m: f64,
        /// Time of the step in s.
        at_s: f64,
    },
    /// An exponential chirp from `f_start_hz` to `f_end_hz` over `duration_s`.
    Chirp {
        /// Amplitude in m.
        amplitude_m: f64,
        /// Start frequency in Hz.
        f_start_hz: f64,
        /// End frequency in Hz.
        f_end_hz: f64,
        /// Sweep duration in s.
        duration_s: f64,
    },
}

/// The feedforward from the reference.
// Plain data in fixed storage (a microcontroller build holds it in a `static`).
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Default)]
pub enum FeedforwardSpec {
    /// Feedback only.
    #[default]
    None,
    /// The stage-model inverse `m·r̈ + c·ṙ + k·r` ([`Stage`]) added to the output, one tick of
    /// preview.
    Model,
    /// A zero-phase-error tracking filter (designed offline from the sampled closed loop): the
    /// reference `preview` ticks ahead through `gain · Π sections`.
    Zpetc(ZpetcSpec),
    /// A finite-impulse-response filter of the reference (designed offline from a measured
    /// FRF): `Σ taps[i] · r[k + preview − i·stride]`.
    Fir(FirSpec),
}

/// The taps of an FIR feedforward filter: the reference the loop follows at tick k is
/// `Σᵢ taps[i] · y_d[k + preview − i·stride]` over the first `taps_used` taps (m/m). Taps
/// `stride` ticks apart reach back far enough to shape a loop's response below a kHz (128 taps
/// one tick apart span 0.6 ms at 199.6 kHz) while the band they flatten stays below
/// `rate / (2·stride)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FirSpec {
    /// The taps (dimensionless, m/m), the first `taps_used`.
    pub taps: [f64; MAX_FIR_TAPS],
    /// Taps in use (1 ..= [`MAX_FIR_TAPS`]).
    pub taps_used: usize,
    /// Ticks of preview: the first tap multiplies the trajectory this far ahead.
    pub preview: usize,
    /// Ticks between taps (≥ 1; `taps_used·stride` ≤ [`MAX_FIR_SPAN`]).
    pub stride: usize,
}

/// The coefficients of a ZPETC feedforward filter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZpetcSpec {
    /// Overall gain (dimensionless, m/m).
    pub gain: f64,
    /// Ticks of preview.
    pub preview: usize,
    /// Second-order sections `[b0, b1, b2, a1, a2]` (`a0 = 1`), the first `sections_used`.
    pub sections: [[f64; 5]; ZPETC_SECTIONS],
    /// Sections in use.
    pub sections_used: usize,
}

impl ZpetcSpec {
    /// The servo-core filter of these coefficients (unused sections are identities).
    pub fn build(&self) -> Result<servo_core::Zpetc<ZPETC_SECTIONS>, servo_core::Error> {
        let mut sections = [servo_core::IirCoeffs::<2>::IDENTITY; ZPETC_SECTIONS];
        let used = &self.sections[..self.sections_used.min(ZPETC_SECTIONS)];
        for (s, &[b0, b1, b2, a1, a2]) in sections.iter_mut().zip(used) {
            *s = servo_core::IirCoeffs::new(b0, [b1, b2], [a1, a2]);
        }
        servo_core::ZpetcConfig {
            gain: self.gain,
            sections,
            preview: self.preview,
        }
        .try_build()
    }
}

impl FeedforwardSpec {
    /// Ticks of reference preview the feedforward needs.
    pub fn preview(&self) -> usize {
        match self {
            FeedforwardSpec::None => 0,
            FeedforwardSpec::Model => 1,
            FeedforwardSpec::Zpetc(z) => z.preview,
            FeedforwardSpec::Fir(f) => f.preview,
        }
    }
}

impl Deployment {
    /// Every number zero, every choice its first (not a loop [`Deployment::check`] accepts):
    /// storage a microcontroller decodes its deployment image into, in place, in a `static`.
    pub const BLANK: Deployment = Deployment {
        servo_rate_hz: 0.0,
        stage: Stage {
            gap_sensitivity_v_per_m: 0.0,
            accel_sensitivity_v_per_m_s2: 0.0,
            suspended_mass_kg: 0.0,
            damping_n_s_per_m: 0.0,
            stiffness_n_per_m: 0.0,
            current_gain_a_per_v: 0.0,
            kt_n_per_a: 0.0,
            dc_gain_m_per_v: 0.0,
        },
        controller: ControllerSpec {
            kind: ControllerKind::Pid,
            pid: PidGains {
                kp: 0.0,
                ki: 0.0,
                kd: 0.0,
                tf_s: 0.0,
            },
            ka: 0.0,
            kg_scaling: false,
            accel_filter_hz: 0.0,
            accel_filter_order: 0,
            ss: None,
            limit_v: 0.0,
        },
        stability: None,
        reference: ReferenceSpec::Hold,
        feedforward: FeedforwardSpec::None,
        smoothing_hz: 0.0,
        protection: ProtectionConfig {
            enabled: false,
            following_error_m: 0.0,
            position_limit_m: None,
            saturation_s: 0.0,
            safe_state: SafeState::Zero,
            retract_m: 0.0,
            retract_speed_m_per_s: 0.0,
            after_trip_s: 0.0,
        },
    };

    /// The thesis prototype as `servo deploy` writes it with no configuration: the Table 5-2
    /// stage (0.074 kg moving mass) at 199.6 kHz under the Chapter 7 PID (§7.5.3), holding
    /// position, default protection; its loop checked on the model: stable for output scales
    /// between ×0.0203 and ×4.409 (12.9 dB of gain margin). (A test keeps it equal to `servo
    /// deploy`'s.)
    pub fn thesis_prototype() -> Self {
        let (k2, k3, kt) = (21965.0, 5e7, 3.6658);
        let mut d = Deployment {
            servo_rate_hz: 199_600.0,
            stage: Stage {
                gap_sensitivity_v_per_m: 160_000.0,
                accel_sensitivity_v_per_m_s2: 1.0 / servo_core::STANDARD_GRAVITY_M_S2,
                suspended_mass_kg: 0.004 + 0.070 + 0.008,
                damping_n_s_per_m: 2.28,
                stiffness_n_per_m: k2,
                current_gain_a_per_v: 1.0,
                kt_n_per_a: kt,
                dc_gain_m_per_v: 1.0 * kt / (k2 * k3 / (k2 + k3) + 0.0),
            },
            controller: ControllerSpec::default(),
            stability: None,
            reference: ReferenceSpec::Hold,
            feedforward: FeedforwardSpec::None,
            smoothing_hz: 0.0,
            protection: ProtectionConfig::default(),
        };
        d.stability = Some(
            Stability {
                spectral_radius: 0.999_998_312_733_224_8,
                unstable_below: 0.020_341_520_958_003_918,
                unstable_above: 4.409_486_610_529_839,
                sha256: Seal::default(),
            }
            .sealed(d.servo_rate_hz, &d.stage, &d.controller),
        );
        d
    }

    /// The servo period in s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.servo_rate_hz
    }

    /// Half the smoothing window in ticks (0: no smoothing).
    pub fn smoothing_half(&self) -> usize {
        if self.smoothing_hz > 0.0 {
            libm::round(self.servo_rate_hz / self.smoothing_hz / 2.0) as usize
        } else {
            0
        }
    }
}
