//! A practice stage for the measure → identify → design workflow on a plant whose truth is
//! hidden: the thesis stage with its Table 5-2 parameters (m1 + m2, k2, c2, m4, k4, c4) drawn
//! from a seed, and what the four-mass model does not contain:
//! - a sensor-mount mode between the gap and its reading at 5–9 kHz,
//!   `(s² + 2ζz·ω·s + ω²)/(s² + 2ζp·ω·s + ω²)` (unit gain at DC and at high frequency, a peak of
//!   ζz/ζp at ω) — always;
//! - [`PracticeEffects`], each on by default and switchable: a mode of the stage inside the
//!   servo band (1.2–2 kHz, on the motor force: the tool feels it — the thesis's stage had
//!   "irregular dynamics at around 1.6 kHz", §6.4.2); a force constant that varies over the
//!   stroke, `K_T(x)/K_T(0) = 1 + a·x/h − b·(x/h)²` with `x` the coil's travel against the
//!   carriage and `h` [`HALF_STROKE_M`]; the suspension stiffness k2 drifting during a run,
//!   `k2·(1 + Δ·(1 − e^(−t/τ)))` (a flexure warming up).
//!
//! The two nonlinear effects act on the command between the DAC and the current amplifier:
//! the DAC's output scaled by `K_T(x)/K_T(0)`, and the drift's spring force `−Δk2(t)·x` added
//! as the command that makes it, both from the previous tick's state (5 µs late; a phase of
//! 3 mrad at 100 Hz). Through the current loop (400 kHz) that is the force itself below a few
//! kHz; the current noise is not scaled and the drift's force passes the in-band mode — effects
//! below 1 % of effects of a few per cent. What a DAQ daemon example serves, so that an
//! identification has something real to find; [`PracticeStage::draw`] reveals it
//! afterwards.

use crate::modes::{ExtraMode, ExtraModes, ModeSite};
use crate::params::{PlantParams, StageParams};
use crate::sim::{CommandChange, SimError, Simulator};
use daq_io::{Backend, Sensor, Truth};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

/// Largest relative deviation of a drawn Table 5-2 parameter from the thesis value.
pub const SPREAD: f64 = 0.15;
/// Range of the mount resonance, Hz.
pub const MOUNT_HZ: (f64, f64) = (5_000.0, 9_000.0);
/// Damping of the mount's pole pair.
pub const MOUNT_ZETA_POLE: f64 = 0.01;
/// Damping of its zero pair (peak ζz/ζp = 2, +6 dB).
pub const MOUNT_ZETA_ZERO: f64 = 0.02;
/// Range of the in-band stage mode, Hz.
pub const BAND_HZ: (f64, f64) = (1_200.0, 2_000.0);

/// The size of each tool-setting error, m.
pub const TOOL_SETTING_M: (f64, f64) = (0.5e-6, 3e-6);
/// Damping of the in-band mode's pole pair.
pub const BAND_ZETA_POLE: f64 = 0.02;
/// Damping of its zero pair (peak +6 dB).
pub const BAND_ZETA_ZERO: f64 = 0.04;
/// Half the stroke `h` over which the force constant varies, m (the sensor's ±25 µm).
pub const HALF_STROKE_M: f64 = 25e-6;
/// Range of the force constant's slope `a` over the half stroke.
pub const FORCE_SLOPE: (f64, f64) = (-0.02, 0.02);
/// Range of its fall-off `b` at the ends of the stroke.
pub const FORCE_FALLOFF: (f64, f64) = (0.02, 0.04);
/// Range of the suspension stiffness's relative drift Δ (the resonance drifts by half of it).
pub const DRIFT: (f64, f64) = (-0.08, -0.03);
/// Time constant of the drift τ, s.
pub const DRIFT_TIME_CONSTANT_S: f64 = 2.0;

/// Which effects beyond the Table 5-2 draw and the mount a practice stage has (all but the
/// tool's setting by default; `run.practice_effects` in a run file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "schema", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields, default)]
pub struct PracticeEffects {
    /// A stage mode at 1.2–2 kHz on the motor force (+6 dB, ζ 0.02).
    pub band_mode: bool,
    /// A force constant that varies over the stroke (slope ±2 %, 2–4 % less at the ends).
    pub force_constant: bool,
    /// The suspension stiffness drifting by −3 to −8 % with a 2 s time constant from the start
    /// of the run.
    pub suspension_drift: bool,
    /// The machine's tool set off by 0.5–3 µm in centre height and in X (either sign): the
    /// setting errors a simulated cut and `servo measure` carry, hidden. Off by default (the
    /// only effect that is): it changes the part, not the loop, and the form errors the book
    /// reports on the practice stage are the loop's.
    pub tool_setting: bool,
}

impl PracticeEffects {
    /// None of them: the Table 5-2 draw and the mount only.
    pub const NONE: PracticeEffects = PracticeEffects {
        band_mode: false,
        force_constant: false,
        suspension_drift: false,
        tool_setting: false,
    };
}

impl Default for PracticeEffects {
    fn default() -> Self {
        PracticeEffects {
            band_mode: true,
            force_constant: true,
            suspension_drift: true,
            tool_setting: false,
        }
    }
}

/// What the seed drew.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PracticeDraw {
    /// The seed.
    pub seed: u64,
    /// The stage (the thesis stage with drawn Table 5-2 parameters).
    pub stage: StageParams,
    /// The mount resonance, Hz.
    pub mount_hz: f64,
    /// The in-band stage mode, Hz (drawn whether or not it is on).
    pub band_hz: f64,
    /// The force constant's slope `a` over the half stroke.
    pub force_slope: f64,
    /// Its fall-off `b` at the ends of the stroke.
    pub force_falloff: f64,
    /// The suspension stiffness's relative drift Δ.
    pub drift: f64,
    /// The tool's setting errors drawn, m: centre height and X offset (drawn whether or not
    /// the effect is on; [`PracticeDraw::tool_setting_m`] says what the machine has).
    pub tool_setting_drawn_m: [f64; 2],
    /// The effects that are on.
    pub effects: PracticeEffects,
}

impl PracticeDraw {
    /// The draw of `seed` around `thesis` (each Table 5-2 parameter within ±[`SPREAD`]; m1 kept,
    /// m2 carrying the change of m1 + m2; the mount within [`MOUNT_HZ`]; then the effects'
    /// values, drawn whether or not `effects` has them on, so that a seed is one stage).
    pub fn draw(seed: u64, thesis: &StageParams, effects: PracticeEffects) -> Self {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
        let mut factor = || 1.0 + SPREAD * (2.0 * rng.random::<f64>() - 1.0);
        let moving = (thesis.m1_kg + thesis.m2_kg) * factor();
        let stage = StageParams {
            m2_kg: moving - thesis.m1_kg,
            k2_n_per_m: thesis.k2_n_per_m * factor(),
            c2_n_s_per_m: thesis.c2_n_s_per_m * factor(),
            m4_kg: thesis.m4_kg * factor(),
            k4_n_per_m: thesis.k4_n_per_m * factor(),
            c4_n_s_per_m: thesis.c4_n_s_per_m * factor(),
            ..*thesis
        };
        let (lo, hi) = MOUNT_HZ;
        let mount_hz = lo * libm::pow(hi / lo, rng.random::<f64>());
        let mut within = |(lo, hi): (f64, f64)| lo + (hi - lo) * rng.random::<f64>();
        let band_hz = BAND_HZ.0 * libm::pow(BAND_HZ.1 / BAND_HZ.0, within((0.0, 1.0)));
        PracticeDraw {
            seed,
            stage,
            mount_hz,
            band_hz,
            force_slope: within(FORCE_SLOPE),
            force_falloff: within(FORCE_FALLOFF),
            drift: within(DRIFT),
            tool_setting_drawn_m: {
                let (lo, hi) = TOOL_SETTING_M;
                let mut one = || {
                    let size = lo + (hi - lo) * rng.random::<f64>();
                    if rng.random::<bool>() {
                        size
                    } else {
                        -size
                    }
                };
                [one(), one()]
            },
            effects,
        }
    }

    /// The tool's centre height and X offset on the machine, m (zero without the effect).
    pub fn tool_setting_m(&self) -> [f64; 2] {
        if self.effects.tool_setting {
            self.tool_setting_drawn_m
        } else {
            [0.0; 2]
        }
    }

    /// The in-band stage mode, on the motor force (None when it is off).
    pub fn band_mode(&self) -> Option<ExtraMode> {
        self.effects.band_mode.then_some(ExtraMode {
            at: ModeSite::Force,
            hz: self.band_hz,
            zeta: BAND_ZETA_POLE,
            zero_hz: self.band_hz,
            zero_zeta: BAND_ZETA_ZERO,
        })
    }

    /// The modes the four-mass model lacks: the mount, and the in-band mode when it is on.
    pub fn modes(&self) -> ExtraModes {
        ExtraModes::new(&[self.mount()])
            .expect("one mode fits")
            .with(self.band_mode().iter())
    }

    /// `K_T(x)/K_T(0)` at the coil's travel `x_m` against the carriage (m): 1 when the effect
    /// is off.
    pub fn force_constant_ratio(&self, x_m: f64) -> f64 {
        if !self.effects.force_constant {
            return 1.0;
        }
        let r = x_m / HALF_STROKE_M;
        1.0 + self.force_slope * r - self.force_falloff * r * r
    }

    /// The suspension stiffness's change at `time_s` into the run, N/m: 0 when the effect is
    /// off.
    pub fn k2_change_n_per_m(&self, time_s: f64) -> f64 {
        if !self.effects.suspension_drift {
            return 0.0;
        }
        self.stage.k2_n_per_m * self.drift * (1.0 - libm::exp(-time_s / DRIFT_TIME_CONSTANT_S))
    }

    /// The mount resonance as the extra mode it is: on the gap reading, a peak of
    /// [`MOUNT_ZETA_ZERO`]/[`MOUNT_ZETA_POLE`] at [`PracticeDraw::mount_hz`] (what the reading
    /// sees of the gap: [`ExtraMode::response`]).
    pub fn mount(&self) -> ExtraMode {
        ExtraMode {
            at: ModeSite::Sensor,
            hz: self.mount_hz,
            zeta: MOUNT_ZETA_POLE,
            zero_hz: self.mount_hz,
            zero_zeta: MOUNT_ZETA_ZERO,
        }
    }
}

/// The practice stage: `plant` with the drawn stage, the mount as a sensor-site extra mode and
/// the effects it has on.
pub struct PracticeStage {
    sim: Simulator,
    draw: PracticeDraw,
    /// Command per newton on the coil, V/N (`1/(K_T·transconductance)`).
    volts_per_newton: f64,
    /// The coil's travel against the carriage `x2 − x3` at the end of the last tick, m.
    coil_travel_m: f64,
    /// Ticks run.
    ticks: u64,
}

impl PracticeStage {
    /// `plant` (its timing, converters, noise) with the stage and mount of `seed`, drawn
    /// around the thesis prototype's stage (Table 5-2) whatever stage and extra modes `plant`
    /// holds — a run's configured plant is its controller's *model* of the practice stage (an
    /// identified one, often), and the stage must not move when the model does; noise seeded
    /// by `seed` too.
    pub fn new(plant: &PlantParams, seed: u64, effects: PracticeEffects) -> Result<Self, SimError> {
        Self::with_noise_seed(plant, seed, seed, effects)
    }

    /// [`PracticeStage::new`] with its noise seeded by `noise_seed` instead: the same stage,
    /// other noise (for repeated measurements of one stage).
    pub fn with_noise_seed(
        plant: &PlantParams,
        seed: u64,
        noise_seed: u64,
        effects: PracticeEffects,
    ) -> Result<Self, SimError> {
        let draw = PracticeDraw::draw(seed, &PlantParams::default().stage, effects);
        let params = PlantParams {
            stage: draw.stage,
            modes: draw.modes(),
            ..*plant
        };
        let sim = Simulator::new(&params, noise_seed, &Default::default())?;
        let a = &params.actuator;
        Ok(PracticeStage {
            sim,
            draw,
            volts_per_newton: 1.0 / (a.kt_n_per_a * a.current_gain_a_per_v),
            coil_travel_m: 0.0,
            ticks: 0,
        })
    }

    /// What the seed drew (for revealing after the workflow, never to the client).
    pub fn draw(&self) -> &PracticeDraw {
        &self.draw
    }

    /// The simulator of the drawn stage, its mount and in-band mode included (the force
    /// constant and the drift are the practice stage's, outside it).
    pub fn simulator(&self) -> &Simulator {
        &self.sim
    }

    /// One tick with `dac_v` (V) and a force `extra_force_n` (N) on the tool (a cut), as
    /// [`Simulator::step_with_force`]: the gap reading through the mount.
    pub fn step_with_force(&mut self, dac_v: f64, extra_force_n: f64) -> Sensor {
        let x = self.coil_travel_m;
        let time_s = self.ticks as f64 * self.sim.period_s();
        let change = CommandChange {
            scale: self.draw.force_constant_ratio(x),
            offset_v: -self.draw.k2_change_n_per_m(time_s) * x * self.volts_per_newton,
        };
        let sensor = self.sim.step_sensor_changed(dac_v, extra_force_n, change);
        let x = self.sim.motion().x_m;
        self.coil_travel_m = x[1] - x[2];
        self.ticks += 1;
        sensor
    }
}

impl Backend for PracticeStage {
    fn step(&mut self, dac_v: f64) -> Sensor {
        self.step_with_force(dac_v, 0.0)
    }

    fn truth(&self) -> Option<Truth> {
        Backend::truth(&self.sim)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_draw_stays_in_its_ranges_and_differs_between_seeds() {
        let thesis = PlantParams::default().stage;
        let all = PracticeEffects::default();
        let a = PracticeDraw::draw(7, &thesis, all);
        assert_eq!(a, PracticeDraw::draw(7, &thesis, all));
        assert_ne!(a, PracticeDraw::draw(8, &thesis, all));
        let ratio = |x: f64, y: f64| (x / y - 1.0).abs();
        assert!(ratio(a.stage.m1_kg + a.stage.m2_kg, thesis.m1_kg + thesis.m2_kg) <= SPREAD);
        for (x, y) in [
            (a.stage.k2_n_per_m, thesis.k2_n_per_m),
            (a.stage.c2_n_s_per_m, thesis.c2_n_s_per_m),
            (a.stage.m4_kg, thesis.m4_kg),
            (a.stage.k4_n_per_m, thesis.k4_n_per_m),
            (a.stage.c4_n_s_per_m, thesis.c4_n_s_per_m),
        ] {
            assert!(ratio(x, y) <= SPREAD && x != y, "{x} vs {y}");
        }
        assert!((MOUNT_HZ.0..=MOUNT_HZ.1).contains(&a.mount_hz));
        assert_eq!(a.stage.m1_kg, thesis.m1_kg);
    }

    /// The stage a seed draws does not depend on the configured stage (the controller's model
    /// of it): a run with an identified model cuts on the stage that was measured.
    #[test]
    fn the_draw_ignores_the_configured_model() {
        let thesis = PlantParams::default();
        let mut identified = thesis;
        identified.stage.m4_kg *= 1.07;
        identified.stage.k2_n_per_m *= 0.9;
        let all = PracticeEffects::default();
        let a = PracticeStage::new(&thesis, 7, all).unwrap();
        let b = PracticeStage::new(&identified, 7, all).unwrap();
        assert_eq!(a.draw(), b.draw());
        assert_eq!(a.draw(), &PracticeDraw::draw(7, &thesis.stage, all));
    }

    /// The draws of the effects stay in their ranges; switching an effect off keeps the
    /// seed's stage and modes (the draw does not depend on the switches).
    #[test]
    fn the_effects_are_drawn_in_their_ranges_whatever_the_switches() {
        let thesis = PlantParams::default().stage;
        for seed in 0..50 {
            let all = PracticeDraw::draw(seed, &thesis, PracticeEffects::default());
            let none = PracticeDraw::draw(seed, &thesis, PracticeEffects::NONE);
            assert_eq!(
                (all.stage, all.mount_hz, all.band_hz),
                (none.stage, none.mount_hz, none.band_hz)
            );
            assert!((BAND_HZ.0..=BAND_HZ.1).contains(&all.band_hz));
            assert!((FORCE_SLOPE.0..=FORCE_SLOPE.1).contains(&all.force_slope));
            assert!((FORCE_FALLOFF.0..=FORCE_FALLOFF.1).contains(&all.force_falloff));
            assert!((DRIFT.0..=DRIFT.1).contains(&all.drift));
            assert_eq!(all.modes().iter().count(), 2);
            assert_eq!(none.modes().iter().count(), 1);
            assert_eq!(
                (none.force_constant_ratio(2e-5), none.k2_change_n_per_m(9.0)),
                (1.0, 0.0)
            );
        }
    }

    /// A plant without noise or converter rounding.
    fn quiet() -> PlantParams {
        let mut plant = PlantParams::default();
        plant.noise = crate::params::NoiseParams {
            sensor: false,
            current: false,
            base: false,
            accel: false,
            ..plant.noise
        };
        (plant.adc.bits, plant.dac.bits) = (0, 0);
        plant
    }

    /// The modes as the stage runs them: the gap reading of a sine through the practice stage
    /// over the reading of the same drawn stage without them is the product of the stated
    /// responses (the mount's peak ζz/ζp = 2 at its frequency, the in-band mode's at its
    /// own, 1 at DC and far above); the true tool position feels the in-band mode only.
    #[test]
    fn the_modes_peak_by_their_damping_ratios_at_their_frequencies() {
        let plant = quiet();
        let fs = plant.timing.servo_rate_hz;
        let effects = PracticeEffects {
            band_mode: true,
            ..PracticeEffects::NONE
        };
        let practice = PracticeStage::new(&plant, 3, effects).unwrap();
        let bare = PlantParams {
            stage: practice.draw().stage,
            ..plant
        };
        // The complex amplitudes of the reading and of the tool at `f` over the last half of
        // 0.2 s.
        let phasors = |stage: &mut dyn Backend, f: f64| {
            let n = (fs * 0.2) as usize;
            let w = 2.0 * std::f64::consts::PI * f / fs;
            let mut sum = [num_complex::Complex64::new(0.0, 0.0); 2];
            for k in 0..n {
                let y = stage.step(1e-3 * libm::sin(w * k as f64)).gap_v;
                let tool = stage.truth().unwrap().tool_m;
                if k >= n / 2 {
                    let turn = num_complex::Complex64::from_polar(1.0, -w * k as f64);
                    sum[0] += y * turn;
                    sum[1] += tool * turn;
                }
            }
            sum
        };
        let truth = practice.draw();
        let (mount, band) = (truth.mount(), truth.band_mode().unwrap());
        for f in [50.0, truth.band_hz, truth.mount_hz, 60_000.0] {
            let mut with = PracticeStage::new(&plant, 3, effects).unwrap();
            let mut without = Simulator::new(&bare, 3, &Default::default()).unwrap();
            let (a, b) = (phasors(&mut with, f), phasors(&mut without, f));
            for (seen, stated, what) in [
                (a[0] / b[0], mount.response(f) * band.response(f), "reading"),
                (a[1] / b[1], band.response(f), "tool"),
            ] {
                assert!(
                    (seen - stated).norm() < 0.01 * stated.norm(),
                    "{what} at {f} Hz: {seen} vs {stated}"
                );
            }
        }
        assert!((mount.response(truth.mount_hz).norm() - 2.0).abs() < 1e-9);
        assert!((band.response(truth.band_hz).norm() - 2.0).abs() < 1e-9);
    }

    /// The motor force of a held `command_v` at the thesis force constant, N.
    fn coil_force_n(command_v: f64) -> f64 {
        let a = quiet().actuator;
        a.kt_n_per_a * a.current_gain_a_per_v * command_v
    }

    /// Holds `command_v` for `seconds` on the quiet practice stage of seed 11 with `effects`;
    /// the coil's travel against the carriage at the end, m, and the drawn truth.
    fn hold(command_v: f64, seconds: f64, effects: PracticeEffects) -> (f64, PracticeDraw) {
        let plant = quiet();
        let mut stage = PracticeStage::new(&plant, 11, effects).unwrap();
        for _ in 0..(seconds * plant.timing.servo_rate_hz) as usize {
            stage.step(command_v);
        }
        (stage.coil_travel_m, *stage.draw())
    }

    /// The force constant over the stroke, by Hooke's law: held still, the suspension's spring
    /// force `k2·x` balances the motor's `K_T(x)·I` — on both sides of mid-stroke, where the
    /// slope and the fall-off act with and against each other — and the travel differs from
    /// the constant force constant's by what `K_T(x)/K_T(0)` says.
    #[test]
    fn a_held_coil_balances_the_force_constant_at_its_travel() {
        let effects = PracticeEffects {
            force_constant: true,
            ..PracticeEffects::NONE
        };
        let mut largest: f64 = 0.0;
        for command_v in [0.12, -0.12] {
            let (x, truth) = hold(command_v, 1.2, effects);
            let force = coil_force_n(command_v);
            let spring = truth.stage.k2_n_per_m * x;
            let ratio = truth.force_constant_ratio(x);
            assert!(
                (spring / (force * ratio) - 1.0).abs() < 1e-4,
                "{spring} vs {force}·{ratio}"
            );
            let (linear, _) = hold(command_v, 1.2, PracticeEffects::NONE);
            assert!(
                (x / linear / ratio - 1.0).abs() < 1e-4,
                "{x} vs {linear}·{ratio}"
            );
            largest = largest.max((ratio - 1.0).abs());
        }
        assert!(largest > 0.01, "the effect is there: {largest}");
    }

    /// The suspension drift, by Hooke's law: a held coil's travel follows the softening spring,
    /// `x(t) = F/(k2·(1 + Δ·(1 − e^(−t/τ))))`, at 1 s and at 2.5 s into the run (the start's ringing gone).
    #[test]
    fn a_held_coil_follows_the_drifting_suspension() {
        let effects = PracticeEffects {
            suspension_drift: true,
            ..PracticeEffects::NONE
        };
        let command_v = 0.1;
        let force = coil_force_n(command_v);
        for t in [1.0, 2.5] {
            let (x, truth) = hold(command_v, t, effects);
            let k2 = truth.stage.k2_n_per_m + truth.k2_change_n_per_m(t);
            assert!(
                (x * k2 / force - 1.0).abs() < 2e-4,
                "{t} s: {x} vs {force}/{k2}"
            );
            assert!(truth.k2_change_n_per_m(t) < -0.005 * truth.stage.k2_n_per_m);
        }
    }
}
