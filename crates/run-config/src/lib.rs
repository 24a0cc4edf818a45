//! # run-config
//!
//! The one configuration of a run (TOML), every default the thesis prototype, errors that name
//! the file, line, key and allowed range — and the stage it describes: the surface of a
//! machining scenario ([`surface`]), the part on the spindle ([`workpiece`]) and the seeded
//! simulated stage behind daq-io's `Backend` ([`SimBackend`], [`simulated_stage`]). What the run
//! planner (`runner`) builds a run from and what libfts_plant serves, without the design tools.

pub mod frf_file;
mod machining;
mod made_for;
mod plant_file;
mod prescription_file;
pub mod presets;
mod realtime;
mod repetitive;
mod sim_backend;
mod stage;
pub mod surface;
pub mod workpiece;

/// Reading the files a run depends on, bounded (the runtime's, shared).
pub mod input_file {
    pub use servo_config::{read_input, read_text, MAX_IMAGE_BYTES, MAX_TEXT_BYTES};
}

pub use machining::{Machining, SurfaceConfig, GRID_EDGE_RADIUS_M};
pub use made_for::{check_made_for, describe_made_for, made_for_plant, plant_toml, sha256_hex};
pub use plant_file::read_plant_file;
pub use prescription_file::read_prescription;
pub use realtime::{RealtimeConfig, Role, WaitKind};
pub use repetitive::{RepetitiveSection, MAX_BINS};
pub use servo_config::{
    line_of, ConfigError, ControllerKind, MadeFor, Origin, PidGains, ProtectionConfig, SafeState,
};
pub use sim_backend::{practice_stage, SimBackend};
pub use stage::{
    plant_error, resolve, simulated_stage, simulator, surface_file, Resolved, StageError,
    SurfaceFile,
};

use plant_sim::cutting::CuttingProfile;
use plant_sim::practice::PracticeEffects;
use plant_sim::PlantParams;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RunConfig {
    /// Duration, seed, statistics window.
    pub run: RunSection,
    /// What the stage is asked to do.
    pub scenario: Scenario,
    /// The controller.
    pub controller: ControllerConfig,
    /// The simulated stage (timing.servo_rate_hz is the loop rate).
    pub plant: PlantParams,
    /// Machine-protection limits and the safe state a trip takes the loop to.
    pub protection: ProtectionConfig,
    /// How the HIL processes run in real time: scheduling, cores, waits, fault settings.
    pub realtime: RealtimeConfig,
}

/// Run length and statistics.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RunSection {
    /// Simulated time in s.
    pub duration_s: f64,
    /// Noise seed.
    pub seed: u64,
    /// Statistics start after this many seconds (the loop and the slow noise filters settle);
    /// unset: 10 % of the duration, at most 0.1 s.
    pub settle_s: Option<f64>,
    /// Simulate the practice stage of this seed instead of the configured one: the Table 5-2
    /// parameters drawn within ±15 %, a sensor-mount resonance and the effects of
    /// `practice_effects`, hidden (`plant_sim::practice`, what the example DAQ daemon serves).
    /// The configured plant is then only the controller's model (its feedforward, its checks):
    /// a run on a stage that is not the model. Unset: the configured stage.
    pub practice_seed: Option<u64>,
    /// The practice stage's effects beyond the draw and the mount, each on unless set false
    /// (`tool_setting` off unless set true):
    /// `band_mode` (a stage mode at 1.2–2 kHz), `force_constant` (K_T varying by a few per cent
    /// over the stroke), `suspension_drift` (k2 drifting by −3 to −8 % with a 2 s time
    /// constant), `tool_setting` (the machine's tool set off by 0.5–3 µm in centre height and
    /// in X: what a simulated cut and `servo measure` carry).
    pub practice_effects: PracticeEffects,
}

impl RunSection {
    /// The statistics window start in s.
    pub fn settle(&self) -> f64 {
        self.settle_s.unwrap_or((0.1 * self.duration_s).min(0.1))
    }
}

impl Default for RunSection {
    fn default() -> Self {
        RunSection {
            duration_s: 1.0,
            seed: 1,
            settle_s: None,
            practice_seed: None,
            practice_effects: PracticeEffects::default(),
        }
    }
}

/// What the stage is asked to do (reference in m, positive away from the workpiece).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum Scenario {
    /// Hold position at 0 (the thesis's positioning-stability test, §5.7.3).
    #[default]
    Hold,
    /// A sine reference.
    Sine {
        /// Amplitude in m.
        amplitude_m: f64,
        /// Frequency in Hz.
        frequency_hz: f64,
    },
    /// A step reference.
    Step {
        /// Step height in m.
        amplitude_m: f64,
        /// Time of the step in s.
        at_s: f64,
    },
    /// An exponential chirp over the whole run.
    Chirp {
        /// Amplitude in m.
        amplitude_m: f64,
        /// Start frequency in Hz.
        f_start_hz: f64,
        /// End frequency in Hz.
        f_end_hz: f64,
    },
    /// Cut a freeform surface along the facing spiral (Ch. 8): the reference is the surface
    /// height under the tool, from the encoder count (see [`Machining`]).
    Machine(Machining),
    /// Hold position during the intermittent cut of §7.6.
    IntermittentCut {
        /// Cutting force in N (0.08 N: Table 7-3's cut, `plant_sim::cutting::TABLE_7_3_FORCE_N`).
        force_n: f64,
        /// Spindle speed in rpm (250, Table 7-3).
        spindle_rpm: f64,
    },
}

impl Scenario {
    /// The scenario's kind as written in the config (`kind = "…"`).
    pub fn name(&self) -> &'static str {
        match self {
            Scenario::Hold => "hold",
            Scenario::Sine { .. } => "sine",
            Scenario::Step { .. } => "step",
            Scenario::Chirp { .. } => "chirp",
            Scenario::Machine(_) => "machine",
            Scenario::IntermittentCut { .. } => "intermittent-cut",
        }
    }

    /// The runtime's reference generator for this scenario over a run of `duration_s` (None
    /// for a machining scenario, whose reference the run supplies from the surface).
    pub fn reference(&self, duration_s: f64) -> Option<servo_config::ReferenceSpec> {
        use servo_config::ReferenceSpec as R;
        Some(match *self {
            Scenario::Hold | Scenario::IntermittentCut { .. } => R::Hold,
            Scenario::Sine {
                amplitude_m,
                frequency_hz,
            } => R::Sine {
                amplitude_m,
                frequency_hz,
            },
            Scenario::Step { amplitude_m, at_s } => R::Step { amplitude_m, at_s },
            Scenario::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
            } => R::Chirp {
                amplitude_m,
                f_start_hz,
                f_end_hz,
                duration_s,
            },
            Scenario::Machine(_) => return None,
        })
    }

    /// The cutting profile this scenario applies.
    pub fn cutting(&self) -> CuttingProfile {
        match *self {
            Scenario::IntermittentCut {
                force_n,
                spindle_rpm,
            } => CuttingProfile::IntermittentCut {
                force_n,
                spindle_rpm,
            },
            _ => CuttingProfile::None,
        }
    }
}

/// The controller.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ControllerConfig {
    /// `pid`, `accel` or `ss`.
    pub kind: ControllerKind,
    /// Position PID gains (for `pid` and `accel`).
    pub pid: PidGains,
    /// Acceleration gain Ka (V/V on accelerometer volts), for `accel` (§7.5: 0, 0.5, 1, 4).
    pub ka: f64,
    /// Multiply the PID gains by 1/Kg (§7.4.1) so reference tracking stays unchanged.
    pub kg_scaling: bool,
    /// Corner of the acceleration shaping filter Ha in Hz; 0 = none. ★ 300 Hz: §7.4.2 leaves
    /// Ha to the user "to maintain closed-loop stability" and prints no value; without it the
    /// inner loop crosses over beyond the accelerometer's 10 kHz band with too much lag and
    /// Ka ≥ 0.5 (light) / ≥ 1 (heavy) is unstable; at 300 Hz Ka 0…4 is stable on both stages
    /// with the fixed PID and on the heavy stage with Kg scaling (200–500 Hz all work).
    pub accel_filter_hz: f64,
    /// Order of Ha: 1 (★ first-order low pass: the inner acceleration loop keeps 90° of
    /// phase, so large Ka stays stable) or 2 (Butterworth: Ka = 4 is unstable at 300 Hz).
    pub accel_filter_order: u8,
    /// Controller file for `ss` (TOML: sample_rate_hz, a, b, c, d), relative to the config file.
    pub ss_file: Option<PathBuf>,
    /// Output limit ±V (the ±10 V DAC).
    pub limit_v: f64,
    /// Feedforward from the reference: `none`, `model` (the stage's inverse
    /// `m·r̈ + c·ṙ + k·r` added to the output, one tick of preview), `zpetc` / `zpetc-sensor`
    /// (zero-phase-error tracking of the whole loop to the tool / to the sensor reading,
    /// designed from the sampled closed-loop model, with the preview it needs; thesis §9.3.1's
    /// missing feedforward) or `fir` (taps fitted to the measured FRF `frf_file`, see
    /// `[controller.fir]`).
    pub feedforward: FeedforwardKind,
    /// What the gains or the controller file were made for (written by `servo tune`; a
    /// controller file carries its own `[made_for]`): checked against this run's plant and
    /// rate, a mismatch refused with both named.
    pub made_for: Option<MadeFor>,
    /// The offline check of the gains' loop (written by `servo tune`): what a running loop
    /// that loads this fragment keeps as its gain range. A run checks its own loop again.
    pub stability: Option<servo_config::Stability>,
    /// Run a controller made for another plant or rate anyway (`--force`).
    pub force: bool,
    /// Zero-phase smoothing of the previewed trajectory before the controller and the
    /// feedforward, in Hz: a Hann window of `rate / smoothing_hz` ticks (about its −6 dB
    /// point), adding half of it to the preview. For surfaces with kinks or steps (beam
    /// integrator, images) whose exact inverse would saturate the DAC; 0 = off.
    pub smoothing_hz: f64,
    /// A measured open-loop FRF of the stage, DAC (V) → measured position (m), as
    /// `servo frf --loop open` writes it (`frf.csv`), relative to the config file: what
    /// `feedforward = "fir"` is fitted to.
    pub frf_file: Option<PathBuf>,
    /// The FIR feedforward's fit (for `feedforward = "fir"`).
    pub fir: FirConfig,
}

/// How an FIR feedforward is fitted to a measured FRF.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct FirConfig {
    /// Number of taps, 1 to 128 (one multiply-add each per tick).
    pub taps: usize,
    /// Ticks of preview the filter reads ahead of the trajectory (at most 62; the sensor's
    /// lag and the loop's phase need a few tens at 199.6 kHz).
    pub preview_ticks: usize,
    /// Ticks between taps (≥ 1, `taps·stride_ticks` at most 2048): the taps span
    /// `taps·stride_ticks` ticks of the trajectory — the loop's response below a kHz needs
    /// milliseconds — and flatten a band below `rate / (2·stride_ticks)`.
    pub stride_ticks: usize,
    /// Upper end of the band made flat, Hz (measured bins above it are not fitted).
    pub band_hz: f64,
    /// Largest gain of the filter above the band (m/m): what it may amplify of a trajectory's
    /// content it was not fitted on.
    pub max_gain: f64,
}

impl Default for FirConfig {
    fn default() -> Self {
        FirConfig {
            taps: 96,
            preview_ticks: 32,
            stride_ticks: 16,
            band_hz: 1500.0,
            max_gain: 2.0,
        }
    }
}

impl ControllerConfig {
    /// The runtime's controller of this configuration, with the matrices of a state-space
    /// controller when `ss` holds them (read from `ss_file`).
    pub fn spec(&self, ss: Option<servo_config::SsMatrices>) -> servo_config::ControllerSpec {
        servo_config::ControllerSpec {
            kind: self.kind,
            pid: self.pid,
            ka: self.ka,
            kg_scaling: self.kg_scaling,
            accel_filter_hz: self.accel_filter_hz,
            accel_filter_order: self.accel_filter_order,
            ss,
            limit_v: self.limit_v,
        }
    }
}

/// Feedforward kinds (see [`ControllerConfig::feedforward`]).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default, schemars::JsonSchema,
)]
#[serde(rename_all = "kebab-case")]
pub enum FeedforwardKind {
    /// Feedback only (the thesis's experiments).
    #[default]
    None,
    /// Velocity, acceleration and stiffness feedforward from the stage model.
    Model,
    /// Zero-phase-error tracking controller (Tomizuka) with preview, inverting the loop from
    /// reference to the true tool position (the form is right; the sensor shows its own lag).
    Zpetc,
    /// The same, inverting the loop from reference to the sensor reading (what a machine's own
    /// FRF measurement gives: the following error vanishes, the tool leads by the sensor lag).
    ZpetcSensor,
    /// An FIR filter of the reference fitted to the measured FRF `controller.frf_file` so
    /// that reference → tool is flat in gain and phase over `controller.fir.band_hz` (the
    /// tool's response from the measured reading and the model's sensor path).
    Fir,
}

impl Default for ControllerConfig {
    fn default() -> Self {
        ControllerConfig {
            kind: ControllerKind::Pid,
            pid: PidGains::default(),
            ka: 0.0,
            kg_scaling: false,
            accel_filter_hz: 300.0,
            accel_filter_order: 1,
            ss_file: None,
            limit_v: 10.0,
            feedforward: FeedforwardKind::None,
            made_for: None,
            stability: None,
            force: false,
            smoothing_hz: 0.0,
            frf_file: None,
            fir: FirConfig::default(),
        }
    }
}

/// A configuration and where it came from (for error locations and relative paths).
#[derive(Debug, Clone, Default)]
pub struct Loaded {
    /// The configuration.
    pub config: RunConfig,
    /// The file it was read from, if any.
    pub origin: Origin,
}

impl Loaded {
    /// Reads and parses `path` (unknown keys are errors).
    pub fn from_file(path: &Path) -> Result<Self, ConfigError> {
        let text = input_file::read_text(path)?;
        let config = toml::from_str(&text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: servo_config::toml_message(&text, &e),
        })?;
        Ok(Loaded {
            config,
            origin: Origin {
                path: Some(path.to_owned()),
                text: Some(text),
            },
        })
    }
}

impl RunConfig {
    /// Servo ticks in the run: duration × servo rate.
    pub fn ticks(&self) -> u64 {
        (self.run.duration_s * self.plant.timing.servo_rate_hz).round() as u64
    }

    /// The resolved configuration as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("the configuration always serialises")
    }

    /// Makes the configuration's relative paths (controller file, surface, repetitive table)
    /// relative to the working directory: they are written relative to the file at `at`.
    pub fn resolve_paths(&mut self, at: &Origin) {
        if let Some(p) = &mut self.controller.ss_file {
            *p = at.resolve(p);
        }
        if let Some(p) = &mut self.controller.frf_file {
            *p = at.resolve(p);
        }
        if let Scenario::Machine(m) = &mut self.scenario {
            if let Some(path) = m.surface.path_mut() {
                *path = at.resolve(path);
            }
            if let Some(table) = m.repetitive.as_mut().and_then(|r| r.table.as_mut()) {
                *table = at.resolve(table);
            }
        }
    }

    /// Checks the run-level values (plant and controller values are checked when built).
    pub fn validate(&self, at: &Origin) -> Result<(), ConfigError> {
        let r = &self.run;
        if !(r.duration_s > 0.0 && r.duration_s <= 86_400.0) {
            return Err(at.invalid("run.duration_s", r.duration_s, "(0, 86400] s"));
        }
        if !(r.settle() >= 0.0 && r.settle() < r.duration_s) {
            return Err(at.invalid("run.settle_s", r.settle(), "[0, run.duration_s) s"));
        }
        let rate = self.plant.timing.servo_rate_hz;
        if !(1e2..=2e6).contains(&rate) {
            return Err(at.invalid("plant.timing.servo_rate_hz", rate, "[100, 2e6] Hz"));
        }
        let nyquist = rate / 2.0;
        match (&self.scenario, self.scenario.reference(r.duration_s)) {
            (_, Some(reference)) => {
                servo_config::check_reference(&reference, nyquist, "scenario")
                    .map_err(|e| at.located(&e))?;
                if let Scenario::Step { at_s, .. } = self.scenario {
                    if !(at_s >= 0.0 && at_s < r.duration_s) {
                        return Err(at.invalid("scenario.at_s", at_s, "[0, run.duration_s) s"));
                    }
                }
            }
            (Scenario::Machine(m), None) => m.validate(at)?,
            (_, None) => {}
        }
        if let Scenario::IntermittentCut {
            force_n,
            spindle_rpm,
        } = self.scenario
        {
            if !(force_n.is_finite() && force_n.abs() <= 100.0) {
                return Err(at.invalid("scenario.force_n", force_n, "[-100, 100] N"));
            }
            if !(spindle_rpm > 0.0 && spindle_rpm <= 1e5) {
                return Err(at.invalid("scenario.spindle_rpm", spindle_rpm, "(0, 1e5] rpm"));
            }
        }
        let c = &self.controller;
        servo_config::check_controller(&c.spec(None), rate).map_err(|e| at.located(&e))?;
        if c.feedforward == FeedforwardKind::Fir {
            self.validate_fir(at, nyquist)?;
        }
        if !(c.smoothing_hz == 0.0 || (c.smoothing_hz > 0.0 && c.smoothing_hz < nyquist)) {
            return Err(at.invalid(
                "controller.smoothing_hz",
                c.smoothing_hz,
                &format!("0 (off) or (0, {nyquist}) Hz"),
            ));
        }
        if c.kind == ControllerKind::Ss && c.ss_file.is_none() {
            return Err(at.invalid(
                "controller.ss_file",
                "(missing)",
                "a controller file for kind = \"ss\"",
            ));
        }
        self.protection
            .check(c.limit_v, self.plant.dc_gain_m_per_v())
            .map_err(|e| at.located(&e))?;
        self.realtime.validate(at, self.plant.period_s())
    }

    /// The FIR feedforward's keys: a measured FRF named, taps, preview and band in range.
    fn validate_fir(&self, at: &Origin, nyquist: f64) -> Result<(), ConfigError> {
        let c = &self.controller;
        if c.frf_file.is_none() {
            return Err(at.invalid(
                "controller.frf_file",
                "(missing)",
                "a measured open-loop FRF (servo frf --loop open writes frf.csv) for feedforward = \"fir\"",
            ));
        }
        let f = &c.fir;
        let most = servo_config::MAX_FIR_TAPS;
        if !(1..=most).contains(&f.taps) {
            return Err(at.invalid("controller.fir.taps", f.taps, &format!("1 to {most}")));
        }
        let preview = servo_config::MAX_PREVIEW;
        if f.preview_ticks > preview {
            return Err(at.invalid(
                "controller.fir.preview_ticks",
                f.preview_ticks,
                &format!("0 to {preview} ticks"),
            ));
        }
        let span = servo_config::MAX_FIR_SPAN;
        if f.stride_ticks == 0 || f.taps * f.stride_ticks > span {
            return Err(at.invalid(
                "controller.fir.stride_ticks",
                f.stride_ticks,
                &format!("at least 1, with taps·stride_ticks at most {span} ticks"),
            ));
        }
        let top = nyquist / f.stride_ticks as f64;
        if !(f.band_hz > 0.0 && f.band_hz < top) {
            return Err(at.invalid(
                "controller.fir.band_hz",
                f.band_hz,
                &format!("(0, {top}) Hz: below half the rate over stride_ticks"),
            ));
        }
        if !(f.max_gain > 0.0 && f.max_gain <= 100.0) {
            return Err(at.invalid("controller.fir.max_gain", f.max_gain, "(0, 100] m/m"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_round_trip_through_toml() {
        let c = RunConfig::default();
        let back: RunConfig = toml::from_str(&c.to_toml()).unwrap();
        assert_eq!(back, c);
        assert_eq!(c.plant.timing.servo_rate_hz, 199_600.0);
        assert_eq!(c.controller.pid.kp, 1.65);
    }

    fn error_of(toml_text: &str) -> String {
        let config: RunConfig = toml::from_str(toml_text).unwrap();
        let at = Origin {
            path: Some("p.toml".into()),
            text: Some(toml_text.into()),
        };
        config.validate(&at).unwrap_err().to_string()
    }

    #[test]
    fn out_of_range_limits_are_located_errors() {
        for (text, key, range) in [
            (
                "[protection]\nretract_m = 2e-3\n",
                "protection.retract_m",
                "1.000e-3",
            ),
            // 0.1 V through 0.167 mm/V reaches 16.7 µm.
            (
                "[controller]\nlimit_v = 0.1\n[protection]\nretract_m = -2e-5\n",
                "protection.retract_m",
                "1.670e-5",
            ),
            (
                "[protection]\nfollowing_error_m = -1e-6\n",
                "protection.following_error_m",
                "1e-3] m",
            ),
            (
                "[protection]\nsaturation_s = nan\n",
                "protection.saturation_s",
                "(0, 10] s",
            ),
            (
                "[protection]\nposition_limit_m = 0.0\n",
                "protection.position_limit_m",
                "(0, 1e-3] m",
            ),
            (
                "[protection]\nafter_trip_s = 2.0\n",
                "protection.after_trip_s",
                "[0, 1] s",
            ),
            (
                "[protection]\nretract_speed_m_per_s = inf\n",
                "protection.retract_speed_m_per_s",
                "(0, 1] m/s",
            ),
        ] {
            let e = error_of(text);
            assert!(
                e.contains("p.toml") && e.contains(key) && e.contains(range),
                "{e}"
            );
        }
        // The default retract (−5 µm = −0.03 V) is within reach.
        let ok: RunConfig = toml::from_str("[protection]\nretract_m = -1e-3\n").unwrap();
        let at = Origin::default();
        assert!(ok.validate(&at).is_ok());
    }
}
