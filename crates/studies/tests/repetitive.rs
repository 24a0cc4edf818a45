//! Repetitive control on the spindle angle in a machining run: the flat-blank grid cut's
//! force-driven form error learned away revolution by revolution at the rate the convergence
//! check predicts, the learned table returned, and a learning law that would diverge on the
//! loop refused before the run.

mod common;

use common::plan;
use runner::config::{FeedforwardKind, Loaded, Machining, RepetitiveSection, Scenario};
use runner::run::RunOptions;
use runner::stop::StopRequest;
use runner::{Plan, RunError};
use studies::form::run_machining;

/// Six revolutions of the grid from a flat blank at 60 rpm (the force swings 0–0.5 N at
/// 200 Hz), no feedforward, with repetitive control `rc`.
fn flat_blank(rc: Option<RepetitiveSection>) -> Loaded {
    let mut cfg = Loaded::default();
    let m = Machining {
        finish_depth_m: None,
        repetitive: rc.map(Box::new),
        ..Machining::default()
    };
    cfg.config.run.duration_s = 6.0;
    cfg.config.run.settle_s = Some(0.05);
    cfg.config.scenario = Scenario::Machine(m);
    cfg.config.controller.feedforward = FeedforwardKind::None;
    cfg
}

/// Learning starts at the second revolution (the first ramps the correction in); with the
/// convergence check's factor κ ≈ 0.5 the error of the low harmonics halves each revolution,
/// so four revolutions later less than a fifth of it is left (the force's 200 Hz is not the
/// slowest harmonic: its factor is smaller still).
#[test]
fn the_flat_blank_cut_error_is_learned_away() {
    let p = plan(&flat_blank(Some(RepetitiveSection::default())));
    let rc = p.repetitive.as_ref().expect("planned");
    assert!(rc.convergence.factor < 0.55, "{:?}", rc.convergence);
    let stop = StopRequest::new();
    let (summary, a) = run_machining(
        &p,
        RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
            digest: false,
        },
    )
    .unwrap();
    let r = a.report();
    let rms = &r.revolution_rms_m;
    assert!(rms.len() >= 6, "{rms:?}");
    // Before learning: the force's deflection (the tutorial's 219 nm over ten revolutions).
    assert!(rms[0] > 150e-9 && rms[1] > 150e-9, "{rms:?}");
    assert!(rms[5] < 0.2 * rms[0], "{rms:?}");
    for w in rms[2..6].windows(2) {
        assert!(w[1] < 0.75 * w[0], "{rms:?}");
    }
    let table = summary.meta.repetitive_table_m.expect("the learned table");
    assert_eq!(table.len(), 4096);
    // The correction is the deflection it cancels: a few hundred nm at most.
    let peak = table.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(peak > 100e-9 && peak < 2e-6, "{peak:e}");
}

/// Without the robustness filter (q₁ = 0) and with no lead, the loop's phase lag turns the
/// correction against the error near the loop's bandwidth: refused before anything runs,
/// naming the key, the harmonic and the factor.
#[test]
fn a_learning_law_that_diverges_is_refused() {
    let cfg = flat_blank(Some(RepetitiveSection {
        q_neighbour: 0.0,
        lead_ticks: Some(0.0),
        learning_gain: 1.0,
        ..RepetitiveSection::default()
    }));
    let err = match Plan::new(&cfg) {
        Err(e) => e,
        Ok(_) => panic!("a diverging law was accepted"),
    };
    let text = err.to_string();
    assert!(matches!(err, RunError::Config(_)), "{text}");
    assert!(
        text.contains("scenario.repetitive.learning_gain") && text.contains("harmonic"),
        "{text}"
    );
    // With the binomial Q and the chosen lead the same gain converges.
    let ok = flat_blank(Some(RepetitiveSection {
        learning_gain: 1.0,
        ..RepetitiveSection::default()
    }));
    assert!(plan(&ok).repetitive.unwrap().convergence.factor < 1.0);
}
