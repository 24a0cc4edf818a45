//! `servo fit` on practice stages whose truth the test reveals: a rational model of the
//! measured open-loop FRF as good as the measurement (within each bin's 95 % disk at ≥ 95 % of
//! the bins), the modes the model lacks (the in-band stage mode and the sensor mount) found
//! within 2 % of their drawn frequencies, and the plant file with them the design tools take.
//! Without the suspension drift (`common::STEADY`), so that the drawn model is the truth.

use crate::common;

use loop_model::closed_loop::ClosedLoop;
use num_complex::Complex64;
use plant_sim::modes::ModeSite;
use plant_sim::practice::PracticeDraw;
use run_config::frf_file::{AccelFrf, MeasuredFrf};
use run_config::Loaded;
use studies::fit::{fit_frf, DEFAULT_MAX_ORDER};

/// The open-loop FRF of practice stage `seed` by stepped sine, 120 points from 20 Hz to 10 kHz
/// (the in-band mode lies at 1.2–2 kHz, the mount at 5–9 kHz).
fn measure(seed: u64) -> MeasuredFrf {
    let mut practice = Loaded::default();
    practice.config.run.practice_seed = Some(seed);
    practice.config.run.practice_effects = common::STEADY;
    let requested = lti::spectral::log_space(20.0, 10_000.0, 120);
    let points = common::open_loop_frf(&common::plan(&practice), &requested);
    MeasuredFrf {
        // Each point's frequency as measured (on its DFT bin), not as requested: near a
        // resonance of ζ = 0.01 the 2·10⁻⁵ difference is 10× the noise.
        freq_hz: points.iter().map(|p| p.freq_hz).collect(),
        response: points
            .iter()
            .map(|p| Complex64::from_polar(p.magnitude, p.phase_deg.to_radians()))
            .collect(),
        coherence: points.iter().map(|p| p.coherence).collect(),
        uncertainty: Some(points.iter().map(|p| p.uncertainty).collect()),
        accel: Some(AccelFrf {
            response: points
                .iter()
                .map(|p| Complex64::from_polar(p.accel_magnitude, p.accel_phase_deg.to_radians()))
                .collect(),
            uncertainty: points.iter().map(|p| p.accel_uncertainty).collect(),
        }),
        source: format!("practice seed {seed}"),
    }
}

#[test]
fn a_practice_stage_is_fitted_within_its_uncertainty_and_its_mount_is_named() {
    for seed in [7, 2026, 2027] {
        let frf = measure(seed);
        let truth = PracticeDraw::draw(seed, &Default::default(), common::STEADY);
        // The model knows the drawn stage, not its modes.
        let mut model = Loaded::default();
        model.config.plant.stage = truth.stage;
        let plan = common::plan(&model);
        let fit = fit_frf(&plan, &frf, None, DEFAULT_MAX_ORDER).unwrap();
        println!(
            "seed {seed}: order {}, {:.1} % within the 95 % disk, weighted RMS {:.2}; tried {:?}",
            fit.order,
            100.0 * fit.within,
            fit.weighted_rms,
            fit.tried
                .iter()
                .map(|t| (t.order, (1000.0 * t.within).round() / 10.0))
                .collect::<Vec<_>>()
        );
        for r in &fit.resonances {
            println!("  {:.1} Hz ζ {:.4} {:?}", r.hz, r.zeta, r.in_model);
        }
        println!(
            "  extra {:?}; in-band {:.1} Hz, mount {:.1} Hz",
            fit.extra_modes, truth.band_hz, truth.mount_hz
        );
        // Against the truth (the drawn stage with its modes, exactly): the fit lies within the
        // measurement's 1σ radius of it at ≥ 95 % of the bins (it averages the noise out).
        let mut exact = model.clone();
        exact.config.plant.modes = truth.modes();
        let exact = common::plan(&exact);
        let open =
            ClosedLoop::open(&exact.sim, exact.config.plant.capa.sensitivity_v_per_m).unwrap();
        let sigma = frf.uncertainty.as_ref().unwrap();
        let inside = frf
            .freq_hz
            .iter()
            .zip(sigma)
            .filter(|(&f, &s)| {
                (fit.fit.response(f) - open.command_response(f).unwrap()).norm() <= s
            })
            .count();
        let share = inside as f64 / frf.freq_hz.len() as f64;
        println!(
            "  the fit within 1σ of the truth at {:.1} % of the bins",
            100.0 * share
        );
        assert!(share >= 0.95, "seed {seed}: {share:.3}");
        // And against the measurement, as close as its noise allows (0.95 expected).
        assert!(fit.within >= 0.9, "seed {seed}: {:.3}", fit.within);
        assert_eq!(
            fit.extra_modes.len(),
            2,
            "seed {seed}: {:?}",
            fit.extra_modes
        );
        // Each where it was drawn, and where it acts: the in-band mode on the motor force, the
        // mount on the reading — told apart by the accelerometer's FRF.
        for (drawn, site) in [
            (truth.band_hz, ModeSite::Force),
            (truth.mount_hz, ModeSite::Sensor),
        ] {
            let off = |hz: f64| (hz / drawn - 1.0).abs();
            let (found, evidence) = fit
                .extra_modes
                .iter()
                .zip(&fit.sites)
                .min_by(|a, b| off(a.0.hz).total_cmp(&off(b.0.hz)))
                .unwrap();
            assert!(
                off(found.hz) < 0.02,
                "seed {seed}: {} Hz vs {drawn} Hz",
                found.hz
            );
            assert_eq!(found.at, site, "seed {seed}, {drawn} Hz: {evidence:?}");
            let e = evidence.unwrap();
            println!("  {drawn:.1} Hz: {}", e.describe());
        }
    }
}

/// A file without each bin's uncertainty cannot be fitted by it: refused, naming the file and
/// the column.
#[test]
fn an_frf_without_uncertainty_is_refused_by_name() {
    let frf = MeasuredFrf {
        uncertainty: None,
        source: "elsewhere/frf.csv".into(),
        ..measure(7)
    };
    let e = fit_frf(
        &common::plan(&Loaded::default()),
        &frf,
        None,
        DEFAULT_MAX_ORDER,
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("elsewhere/frf.csv") && e.contains("uncertainty_m_per_v"),
        "{e}"
    );
}
