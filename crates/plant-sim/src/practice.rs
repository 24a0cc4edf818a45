//! A practice stage for the measure → identify → design workflow on a plant whose truth is
//! hidden: the thesis stage with its Table 5-2 parameters (m1 + m2, k2, c2, m4, k4, c4) drawn
//! from a seed, and one resonance the four-mass model does not contain — a sensor-mount mode
//! between the gap and its reading, `(s² + 2ζz·ω·s + ω²)/(s² + 2ζp·ω·s + ω²)` (unit gain at DC
//! and at high frequency, a peak of ζz/ζp at ω). What a DAQ daemon example serves, so that an
//! identification has something real to find; [`PracticeStage::truth`] reveals the draw
//! afterwards.

use crate::modes::{ExtraMode, ExtraModes, ModeSite};
use crate::params::{PlantParams, StageParams};
use crate::sim::{SimError, Simulator};
use daq_io::{Backend, Sensor, Truth};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::Serialize;

/// Largest relative deviation of a drawn Table 5-2 parameter from the thesis value.
pub const SPREAD: f64 = 0.15;
/// Range of the mount resonance, Hz.
pub const MOUNT_HZ: (f64, f64) = (5_000.0, 9_000.0);
/// Damping of the mount's pole pair.
pub const MOUNT_ZETA_POLE: f64 = 0.01;
/// Damping of its zero pair (peak ζz/ζp = 2, +6 dB).
pub const MOUNT_ZETA_ZERO: f64 = 0.02;

/// What the seed drew.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PracticeTruth {
    /// The seed.
    pub seed: u64,
    /// The stage (the thesis stage with drawn Table 5-2 parameters).
    pub stage: StageParams,
    /// The mount resonance, Hz.
    pub mount_hz: f64,
}

impl PracticeTruth {
    /// The draw of `seed` around `thesis` (each Table 5-2 parameter within ±[`SPREAD`]; m1 kept,
    /// m2 carrying the change of m1 + m2; the mount within [`MOUNT_HZ`]).
    pub fn draw(seed: u64, thesis: &StageParams) -> Self {
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
        PracticeTruth {
            seed,
            stage,
            mount_hz,
        }
    }

    /// The mount resonance as the extra mode it is: on the gap reading, a peak of
    /// [`MOUNT_ZETA_ZERO`]/[`MOUNT_ZETA_POLE`] at [`PracticeTruth::mount_hz`] (what the reading
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

/// The practice stage: `plant` with the drawn stage and the mount as a sensor-site extra mode.
pub struct PracticeStage {
    sim: Simulator,
    truth: PracticeTruth,
}

impl PracticeStage {
    /// `plant` (its timing, converters, noise) with the stage and mount of `seed`, drawn
    /// around the thesis prototype's stage (Table 5-2) whatever stage and extra modes `plant`
    /// holds — a run's configured plant is its controller's *model* of the practice stage (an
    /// identified one, often), and the stage must not move when the model does; noise seeded
    /// by `seed` too.
    pub fn new(plant: &PlantParams, seed: u64) -> Result<Self, SimError> {
        Self::with_noise_seed(plant, seed, seed)
    }

    /// [`PracticeStage::new`] with its noise seeded by `noise_seed` instead: the same stage,
    /// other noise (for repeated measurements of one stage).
    pub fn with_noise_seed(
        plant: &PlantParams,
        seed: u64,
        noise_seed: u64,
    ) -> Result<Self, SimError> {
        let truth = PracticeTruth::draw(seed, &PlantParams::default().stage);
        let params = PlantParams {
            stage: truth.stage,
            modes: ExtraModes::new(&[truth.mount()]).expect("one mode fits"),
            ..*plant
        };
        let sim = Simulator::new(&params, noise_seed, &Default::default())?;
        Ok(PracticeStage { sim, truth })
    }

    /// What the seed drew (for revealing after the workflow, never to the client).
    pub fn truth(&self) -> &PracticeTruth {
        &self.truth
    }

    /// The simulator of the drawn stage, its mount included.
    pub fn simulator(&self) -> &Simulator {
        &self.sim
    }

    /// One tick with `dac_v` (V) and a force `extra_force_n` (N) on the tool (a cut), as
    /// [`Simulator::step_with_force`]: the gap reading through the mount.
    pub fn step_with_force(&mut self, dac_v: f64, extra_force_n: f64) -> Sensor {
        self.sim.step_sensor(dac_v, extra_force_n)
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
        let a = PracticeTruth::draw(7, &thesis);
        assert_eq!(a, PracticeTruth::draw(7, &thesis));
        assert_ne!(a, PracticeTruth::draw(8, &thesis));
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
        let a = PracticeStage::new(&thesis, 7).unwrap();
        let b = PracticeStage::new(&identified, 7).unwrap();
        assert_eq!(a.truth(), b.truth());
        assert_eq!(a.truth(), &PracticeTruth::draw(7, &thesis.stage));
    }

    /// The mount as the stage runs it: the gap reading of a sine through the practice stage
    /// over the reading of the same drawn stage without it is the stated mount response —
    /// ζz/ζp = 2 at the mount's frequency, 1 at DC and far above.
    #[test]
    fn the_mount_peaks_by_the_damping_ratio_at_its_frequency() {
        let mut plant = PlantParams::default();
        plant.noise = crate::params::NoiseParams {
            sensor: false,
            current: false,
            base: false,
            accel: false,
            ..plant.noise
        };
        (plant.adc.bits, plant.dac.bits) = (0, 0);
        let fs = plant.timing.servo_rate_hz;
        let practice = PracticeStage::new(&plant, 3).unwrap();
        let bare = PlantParams {
            stage: practice.truth().stage,
            ..plant
        };
        // The complex amplitude of the reading at `f` over the last half of 0.2 s.
        let phasor = |stage: &mut dyn Backend, f: f64| {
            let n = (fs * 0.2) as usize;
            let w = 2.0 * std::f64::consts::PI * f / fs;
            let mut sum = num_complex::Complex64::new(0.0, 0.0);
            for k in 0..n {
                let y = stage.step(1e-3 * libm::sin(w * k as f64)).gap_v;
                if k >= n / 2 {
                    sum += y * num_complex::Complex64::from_polar(1.0, -w * k as f64);
                }
            }
            sum
        };
        let fr = practice.truth().mount_hz;
        let mount = practice.truth().mount();
        for f in [50.0, fr, 60_000.0] {
            let mut with = PracticeStage::new(&plant, 3).unwrap();
            let mut without = Simulator::new(&bare, 3, &Default::default()).unwrap();
            let seen = phasor(&mut with, f) / phasor(&mut without, f);
            let stated = mount.response(f);
            assert!(
                (seen - stated).norm() < 0.01 * stated.norm(),
                "{f} Hz: {seen} vs {stated}"
            );
        }
        assert!((mount.response(fr).norm() - 2.0).abs() < 1e-9);
    }
}
