//! Designs and checks on a measured FRF, judged against independent truth: an FRF that is the
//! model's exact response (so the measured loop must be the model's), with a stated
//! uncertainty that the repetitive controller's check must take at its worst.

use loop_model::closed_loop::{input, output, reference_path_response, ClosedLoop};
use loop_model::measured_loop::MeasuredLoop;
use lti::FrequencyResponse;
use num_complex::Complex64;
use run_config::frf_file::MeasuredFrf;
use run_config::{ControllerKind, FeedforwardKind, Loaded, Machining, RepetitiveSection, Scenario};
use runner::Plan;
use std::path::Path;

/// `frf.csv` of the plan's model, open loop, at 80 points from 20 Hz to 5 kHz, each point's
/// uncertainty `relative` of its magnitude.
fn model_frf(plan: &Plan, relative: f64, path: &Path) {
    scaled_model_frf(plan, 1.0, relative, (20.0, 5000.0), path);
}

/// `frf.csv` of a stage `gain` times the plan's model, open loop, at 80 points over `band_hz`,
/// each point's uncertainty `relative` of its magnitude.
fn scaled_model_frf(plan: &Plan, gain: f64, relative: f64, band_hz: (f64, f64), path: &Path) {
    let open = ClosedLoop::open(&plan.sim, plan.config.plant.capa.sensitivity_v_per_m).unwrap();
    let mut csv = String::from(
        "# fts-servo frf: quantity = P (the model)\nfreq_hz,magnitude_m_per_v,phase_deg,coherence,uncertainty_m_per_v\n",
    );
    for f in lti::spectral::log_space(band_hz.0, band_hz.1, 80) {
        let p = gain * open.command_response(f).unwrap();
        csv += &format!(
            "{f:.9},{:.15e},{:.12},1,{:.6e}\n",
            p.norm(),
            p.arg().to_degrees(),
            relative * p.norm()
        );
    }
    std::fs::write(path, csv).unwrap();
}

fn machining(repetitive: Option<RepetitiveSection>) -> Loaded {
    let mut loaded = Loaded::default();
    loaded.config.scenario = Scenario::Machine(Machining {
        repetitive: repetitive.map(Box::new),
        ..Default::default()
    });
    loaded
}

/// Fitted to the model's own FRF, the FIR makes the model's loop flat: what the runtime's
/// filter does to the reference (`servo_config::reference_path`, the runtime's formula)
/// through the model's closed loop to the tool is 1 within the fit's stated residual.
#[test]
fn an_fir_on_the_models_frf_flattens_the_models_loop() {
    let dir = tempfile::tempdir().unwrap();
    let frf = dir.path().join("frf.csv");
    let mut loaded = machining(None);
    model_frf(&Plan::new(&loaded).unwrap(), 0.0, &frf);
    loaded.config.controller.feedforward = FeedforwardKind::Fir;
    loaded.config.controller.frf_file = Some(frf);
    let plan = Plan::new(&loaded).unwrap();
    let fit = plan.fir.as_ref().unwrap();
    assert!(fit.worst_residual < 0.01, "{fit}");
    let through = reference_path_response(&plan.closed_loop, &plan.deployment, output::TOOL_M);
    for f in [50.0, 200.0, 455.0, 800.0, 1050.0, 1400.0] {
        let flat = (through(f) - Complex64::new(1.0, 0.0)).norm();
        assert!(
            flat < 1.5 * fit.worst_residual + 1e-3,
            "{f} Hz: |T·H − 1| = {flat} ({fit})"
        );
    }
}

/// The repetitive controller checked on a measured FRF: on the model's exact FRF it finds the
/// model's own factor; the same data stated with 60 % uncertainty per point slow the worst
/// harmonic (its disk's worst point); with 200 % the law is refused, naming the harmonic and
/// the data it was checked on.
#[test]
fn repetitive_control_is_checked_over_the_measured_disks() {
    let dir = tempfile::tempdir().unwrap();
    let law = RepetitiveSection {
        learning_gain: 0.9,
        ..Default::default()
    };
    let model = Plan::new(&machining(Some(law.clone()))).unwrap();
    let on_model = model.repetitive.as_ref().unwrap().convergence;
    assert_eq!(
        model.repetitive.as_ref().unwrap().checked_on,
        "the model's loop"
    );
    let checked = |relative: f64| {
        let frf = dir.path().join(format!("frf-{relative}.csv"));
        model_frf(&model, relative, &frf);
        let mut loaded = machining(Some(law.clone()));
        loaded.config.controller.frf_file = Some(frf);
        Plan::new(&loaded).map(|plan| plan.repetitive.unwrap())
    };
    let exact = checked(0.0).unwrap();
    assert!(
        exact.checked_on.contains("measured FRF"),
        "{}",
        exact.checked_on
    );
    assert!(
        (exact.convergence.factor - on_model.factor).abs() < 1e-6,
        "{:?} vs the model's {on_model:?}",
        exact.convergence
    );
    let uncertain = checked(0.6).unwrap().convergence;
    assert!(
        uncertain.factor > on_model.factor + 0.2 && uncertain.factor < 1.0,
        "{uncertain:?} vs the model's {on_model:?}"
    );
    let e = checked(2.0).unwrap_err().to_string();
    assert!(
        e.contains("Hz) a revolution") && e.contains("measured FRF"),
        "{e}"
    );
}

/// The feedback loop checked on a measured FRF agrees with the eigenvalues of the sampled
/// closed loop: a stage `g` times the model is the model's loop with the controller's output
/// scaled by `g`, which `gain_range` finds stable only between its two limits (by the spectral
/// radius, not by frequency responses). Measured from 20 Hz to 90 kHz, the loop is accepted 2 %
/// inside either limit and refused 2 % outside as unstable; 2 % inside with each bin's
/// uncertainty 5 % of its magnitude, the disks reach −1 and it is refused as allowing
/// instability; the deployment's gain range is what both loops allow (the stage's limits are
/// the model's divided by `g`).
#[test]
fn the_loop_on_a_measured_frf_is_as_stable_as_its_eigenvalues_say() {
    let dir = tempfile::tempdir().unwrap();
    let model = Plan::new(&Loaded::default()).unwrap();
    let range = runner::gain_range::gain_range(&model).unwrap();
    let (low, high) = (range.unstable_below, range.unstable_above);
    assert!(low > 0.0 && high.is_finite(), "{low} {high}");
    let checked = |gain: f64, relative: f64| {
        let frf = dir.path().join(format!("frf-{gain}-{relative}.csv"));
        scaled_model_frf(&model, gain, relative, (20.0, 90_000.0), &frf);
        let mut loaded = Loaded::default();
        loaded.config.controller.frf_file = Some(frf);
        let plan = Plan::new(&loaded).unwrap();
        plan.check_stable().map(|_| plan)
    };
    for gain in [high / 1.02, low * 1.02] {
        let plan = checked(gain, 0.0).unwrap();
        let on_measured = runner::gain_range::gain_range(&plan).unwrap();
        for (got, want) in [
            (on_measured.unstable_above, (high / gain).min(high)),
            (on_measured.unstable_below, (low / gain).max(low)),
        ] {
            assert!(
                (got / want - 1.0).abs() < 2e-3,
                "g = {gain}: {got} vs {want}"
            );
        }
    }
    for gain in [high * 1.02, low / 1.02] {
        let e = checked(gain, 0.0)
            .err()
            .expect("unstable on the measurement");
        assert!(e.to_string().contains("is unstable"), "g = {gain}: {e}");
    }
    let e = checked(high / 1.02, 0.05)
        .err()
        .expect("the disks reach −1");
    assert!(e.to_string().contains("allows an unstable loop"), "{e}");
}

/// Closed on the model's own open-loop response, the measured loop is the model's closed
/// loop (reference → tool) to rounding: the PID, and the acceleration loop whose
/// accelerometer path comes from the model.
#[test]
fn on_the_models_own_frf_it_is_the_models_loop() {
    for (kind, ka) in [(ControllerKind::Pid, 0.0), (ControllerKind::Accel, 1.0)] {
        let mut loaded = Loaded::default();
        loaded.config.controller.kind = kind;
        loaded.config.controller.ka = ka;
        let plan = Plan::new(&loaded).unwrap();
        let s = plan.config.plant.capa.sensitivity_v_per_m;
        let open = ClosedLoop::open(&plan.sim, s).unwrap();
        let freq_hz = lti::spectral::log_space(10.0, 20_000.0, 40);
        let frf = MeasuredFrf {
            response: freq_hz
                .iter()
                .map(|&f| open.command_response(f).unwrap())
                .collect(),
            coherence: vec![1.0; freq_hz.len()],
            uncertainty: None,
            accel: None,
            source: "the model".into(),
            freq_hz,
        };
        let m = MeasuredLoop::new(&frf, &open, &plan.controller.linear, s).unwrap();
        for (f, t) in m.freq_hz.iter().zip(&m.reference_to_tool) {
            let want = plan
                .closed_loop
                .response(output::TOOL_M, input::REFERENCE_M, *f)
                .unwrap();
            assert!(
                (t / want - 1.0).norm() < 1e-8,
                "{kind:?} {f} Hz: {t} vs {want}"
            );
        }
        assert!(m.uncertainty.iter().all(|u| *u == 0.0));
        let l = FrequencyResponse::new(&open.loop_gain(&plan.controller.linear, s).unwrap());
        for (f, (g, _)) in m.freq_hz.iter().zip(&m.loop_gain) {
            let want = l.discrete(*f, open.period_s).unwrap()[(0, 0)];
            assert!(
                (g / want - 1.0).norm() < 1e-8,
                "{kind:?} {f} Hz: L {g} vs {want}"
            );
        }
        let model_loop = |f: f64| l.discrete(f, open.period_s).unwrap()[(0, 0)];
        let on_model = design::loops::margins(model_loop, 1.0, 0.499 / open.period_s);
        let got = m.stability.margins;
        for (a, b) in [
            (got.phase_margin_deg, on_model.phase_margin_deg),
            (got.gain_margin_db, on_model.gain_margin_db),
            (got.lower_gain_margin_db, on_model.lower_gain_margin_db),
        ] {
            let (a, b) = (a.unwrap(), b.unwrap());
            assert!((a - b).abs() < 1e-6, "{kind:?}: {a} vs the model's {b}");
        }
        assert!(m.stability.verdict.robustly_stable(), "{kind:?}");
    }
}
