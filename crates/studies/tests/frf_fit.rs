//! `servo fit` on practice stages whose truth the test reveals: a rational model of the
//! measured open-loop FRF as good as the measurement (within each bin's 95 % disk at ≥ 95 % of
//! the bins), the sensor-mount resonance the model lacks found within 2 % of its drawn
//! frequency, and the plant file with it the design tools take.

use crate::common;

use num_complex::Complex64;
use plant_sim::modes::ExtraModes;
use plant_sim::practice::PracticeTruth;
use run_config::frf_file::MeasuredFrf;
use run_config::Loaded;
use runner::closed_loop::ClosedLoop;
use studies::fit::{fit_frf, DEFAULT_MAX_ORDER};

/// The open-loop FRF of practice stage `seed` by stepped sine, 120 points from 20 Hz to 10 kHz
/// (the mount lies at 5–9 kHz).
fn measure(seed: u64) -> MeasuredFrf {
    let mut practice = Loaded::default();
    practice.config.run.practice_seed = Some(seed);
    let freq_hz = lti::spectral::log_space(20.0, 10_000.0, 120);
    let points = common::open_loop_frf(&common::plan(&practice), &freq_hz);
    MeasuredFrf {
        freq_hz,
        response: points
            .iter()
            .map(|p| Complex64::from_polar(p.magnitude, p.phase_deg.to_radians()))
            .collect(),
        coherence: points.iter().map(|p| p.coherence).collect(),
        uncertainty: Some(points.iter().map(|p| p.uncertainty).collect()),
        source: format!("practice seed {seed}"),
    }
}

#[test]
fn a_practice_stage_is_fitted_within_its_uncertainty_and_its_mount_is_named() {
    for seed in [7, 2026, 2027] {
        let frf = measure(seed);
        let truth = PracticeTruth::draw(seed, &Default::default());
        // The model knows the drawn stage, not the mount.
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
            "  extra {:?}; mount {:.1} Hz",
            fit.extra_modes, truth.mount_hz
        );
        // Against the truth (the drawn stage with its mount, exactly): the fit lies within the
        // measurement's 1σ radius of it at ≥ 95 % of the bins (it averages the noise out).
        let mut exact = model.clone();
        exact.config.plant.modes = ExtraModes::new(&[truth.mount()]).unwrap();
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
            1,
            "seed {seed}: {:?}",
            fit.extra_modes
        );
        let found = fit.extra_modes[0].hz;
        assert!(
            (found / truth.mount_hz - 1.0).abs() < 0.02,
            "seed {seed}: {found} Hz vs {} Hz",
            truth.mount_hz
        );
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
