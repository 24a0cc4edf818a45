//! A practice stage for the measure → identify → design workflow on a plant whose truth is
//! hidden: the thesis stage with its Table 5-2 parameters (m1 + m2, k2, c2, m4, k4, c4) drawn
//! from a seed, and one resonance the four-mass model does not contain — a sensor-mount mode
//! between the gap and its reading, `(s² + 2ζz·ω·s + ω²)/(s² + 2ζp·ω·s + ω²)` (unit gain at DC
//! and at high frequency, a peak of ζz/ζp at ω). What a DAQ daemon example serves, so that an
//! identification has something real to find; [`PracticeStage::truth`] reveals the draw
//! afterwards.

use crate::params::{PlantParams, StageParams};
use crate::sim::{SimError, Simulator};
use daq_io::{Backend, Sensor, Truth};
use lti::StateSpace;
use nalgebra::DMatrix;
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
}

/// The practice stage: `plant` with the drawn stage, its reading through the mount.
pub struct PracticeStage {
    sim: Simulator,
    truth: PracticeTruth,
    /// The mount, discretised (Tustin, pre-warped at its frequency): x ← A·x + B·g,
    /// reading = C·x + D·g.
    mount: ([[f64; 2]; 2], [f64; 2], [f64; 2], f64),
    x: [f64; 2],
}

impl PracticeStage {
    /// `plant` (its timing, converters, noise) with the stage and mount of `seed`, drawn
    /// around the thesis prototype's stage (Table 5-2) whatever stage `plant` holds — a run's
    /// configured stage is its controller's *model* of the practice stage (an identified one,
    /// often), and the stage must not move when the model does; noise seeded by `seed` too.
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
            ..*plant
        };
        let sim = Simulator::new(&params, noise_seed, &Default::default())?;
        let w = 2.0 * std::f64::consts::PI * truth.mount_hz;
        let continuous = StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * MOUNT_ZETA_POLE * w]),
            b: DMatrix::from_row_slice(2, 1, &[0.0, 1.0]),
            c: DMatrix::from_row_slice(1, 2, &[0.0, 2.0 * (MOUNT_ZETA_ZERO - MOUNT_ZETA_POLE) * w]),
            d: DMatrix::from_element(1, 1, 1.0),
        };
        let d = lti::discretise::c2d_tustin(&continuous, sim.period_s(), Some(truth.mount_hz))
            .expect("a damped second-order section discretises");
        let mount = (
            [[d.a[(0, 0)], d.a[(0, 1)]], [d.a[(1, 0)], d.a[(1, 1)]]],
            [d.b[(0, 0)], d.b[(1, 0)]],
            [d.c[(0, 0)], d.c[(0, 1)]],
            d.d[(0, 0)],
        );
        Ok(PracticeStage {
            sim,
            truth,
            mount,
            x: [0.0; 2],
        })
    }

    /// What the seed drew (for revealing after the workflow, never to the client).
    pub fn truth(&self) -> &PracticeTruth {
        &self.truth
    }

    /// The mount's response at `f_hz` (its discrete form, at the servo period): what the
    /// reading sees of the gap, dimensionless (for judging a measurement against the truth; NaN
    /// on a pole of the discretised mount, which damping keeps off the unit circle).
    pub fn mount_response(&self, f_hz: f64) -> num_complex::Complex64 {
        let (a, b, c, d) = &self.mount;
        let mount = StateSpace {
            a: DMatrix::from_row_slice(2, 2, &[a[0][0], a[0][1], a[1][0], a[1][1]]),
            b: DMatrix::from_row_slice(2, 1, b),
            c: DMatrix::from_row_slice(1, 2, c),
            d: DMatrix::from_element(1, 1, *d),
        };
        mount
            .freq_response_discrete(f_hz, self.sim.period_s())
            .map_or(num_complex::Complex64::new(f64::NAN, f64::NAN), |h| {
                h[(0, 0)]
            })
    }

    /// The simulator of the drawn stage (before the mount).
    pub fn simulator(&self) -> &Simulator {
        &self.sim
    }

    /// One tick with `dac_v` (V) and a force `extra_force_n` (N) on the tool (a cut), as
    /// [`Simulator::step_with_force`], the gap reading through the mount.
    pub fn step_with_force(&mut self, dac_v: f64, extra_force_n: f64) -> Sensor {
        let s = self.sim.step_sensor(dac_v, extra_force_n);
        Sensor {
            gap_v: self.through_mount(s.gap_v),
            ..s
        }
    }

    /// The gap reading `g` (V) through the mount.
    fn through_mount(&mut self, g: f64) -> f64 {
        let (a, b, c, d) = &self.mount;
        let y = c[0] * self.x[0] + c[1] * self.x[1] + d * g;
        self.x = [
            a[0][0] * self.x[0] + a[0][1] * self.x[1] + b[0] * g,
            a[1][0] * self.x[0] + a[1][1] * self.x[1] + b[1] * g,
        ];
        y
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

    /// The mount alone: a sine at its frequency comes out ζz/ζp = 2 times larger; at DC and
    /// far above, unchanged.
    #[test]
    fn the_mount_peaks_by_the_damping_ratio_at_its_frequency() {
        let plant = PlantParams::default();
        let fs = plant.timing.servo_rate_hz;
        let amplitude = |f: f64| {
            let mut stage = PracticeStage::new(&plant, 3).unwrap();
            let n = (fs * 0.2) as usize;
            let mut peak: f64 = 0.0;
            for k in 0..n {
                let y =
                    stage.through_mount(libm::sin(2.0 * std::f64::consts::PI * f * k as f64 / fs));
                if k > n / 2 {
                    peak = peak.max(y.abs());
                }
            }
            peak
        };
        let stage = PracticeStage::new(&plant, 3).unwrap();
        let fr = stage.truth().mount_hz;
        assert!((amplitude(fr) - 2.0).abs() < 0.01, "{}", amplitude(fr));
        // The response the stage states agrees with the filter it runs.
        for f in [50.0, fr, 60_000.0] {
            let stated = stage.mount_response(f).norm();
            assert!((stated - amplitude(f)).abs() < 0.02, "{f} Hz: {stated}");
        }
        assert!((amplitude(50.0) - 1.0).abs() < 0.01);
        assert!((amplitude(60_000.0) - 1.0).abs() < 0.02);
    }
}
