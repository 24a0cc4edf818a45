//! A prescription's predicted form error against the simulated cut (the frequency-domain
//! prediction through the loop model beside the time-domain simulation with its noise and
//! cutting force), and the predicted error map written as a sag grid, read back as the
//! prescription's `[compensation]`, removing most of the error of the next cut.

use crate::common;
use common::GENTLE;

use common::machine;
use run_config::{Loaded, Origin, RunConfig, RunSection, Scenario};
use std::path::Path;

/// A plan cutting the prescription file `path` at 600 rpm from the aperture's edge.
fn plan(path: &Path, duration_s: f64) -> runner::Plan {
    let config = RunConfig {
        run: RunSection {
            duration_s,
            ..RunSection::default()
        },
        scenario: Scenario::Machine(common::gentle_cut(path)),
        ..RunConfig::default()
    };
    common::plan(&Loaded {
        config,
        origin: Origin::default(),
    })
}

#[test]
fn the_predicted_band_error_is_the_simulated_cuts() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("gentle.toml");
    std::fs::write(&file, GENTLE).unwrap();
    let p = plan(&file, 0.6);
    let predicted = studies::toolpath::demands::feasibility(&p, 10)
        .unwrap()
        .bands[0]
        .predicted_rms_m;
    let (_, analysis) = machine(&p);
    let simulated = analysis.report().form_error_m.rms;
    // The band 9.95–10 mm against the prediction's 9–10 mm band (its edge the largest).
    assert!(
        (simulated - predicted).abs() < 0.1 * predicted,
        "simulated {simulated:e} m, predicted {predicted:e} m"
    );
}

#[test]
fn the_predicted_error_loaded_back_compensates_the_next_cut() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("gentle.toml");
    std::fs::write(&file, GENTLE).unwrap();
    let first = studies::toolpath::study(&plan(&file, 0.6), 4).unwrap();
    let (_, cut) = machine(&plan(&file, 0.6));
    let simulated_before = cut.report().form_error_m.rms;
    let before = first.form.tilt_removed.rms_m;
    assert!(before > 3e-9, "the PID loop leaves nanometres: {before:e}");
    let p = plan(&file, 0.6);
    let Some(run_config::surface::LoadedSurface::Prescription(path)) = &p.surface else {
        panic!("a prescription")
    };
    let table = studies::toolpath::TableSize {
        radii: 4,
        counts: 8,
        pulses_per_rev: 80_000,
    };
    let out = dir.path().join("first");
    studies::toolpath::write_data(&first, path, table, &out).unwrap();
    // The pitch as the file states it (its first line), as a user would copy it.
    let text = std::fs::read_to_string(out.join("part_error.csv")).unwrap();
    let header = text.lines().next().unwrap();
    let pitch_mm: f64 = header
        .rsplit("pitch ")
        .next()
        .and_then(|t| t.trim_end_matches(" mm").parse().ok())
        .expect("the header states the pitch");
    let compensated = dir.path().join("compensated.toml");
    std::fs::write(
        &compensated,
        format!(
            "{GENTLE}\n[compensation]\npath = \"first/part_error.csv\"\npitch_mm = [{pitch_mm}, {pitch_mm}]\n"
        ),
    )
    .unwrap();
    let second = studies::toolpath::study(&plan(&compensated, 0.6), 4).unwrap();
    // Part = (design − e₁) + e₂ with e₂ the loop's error on the compensated path: what is left
    // is e₂ − e₁, the loop's error on e₁ itself (|T − 1| of it) and the grid's interpolation.
    let after = second.form.tilt_removed.rms_m;
    assert!(
        after < 0.2 * before,
        "after {after:e} m, before {before:e} m"
    );
    // The simulated cut agrees: its form error, against the design, falls as predicted.
    let (_, cut) = machine(&plan(&compensated, 0.6));
    let simulated = cut.report().form_error_m.rms;
    assert!(
        simulated < 0.1 * simulated_before,
        "simulated {simulated:e} m against {simulated_before:e} m before"
    );
}
