//! The intermittent cut of thesis §7.6 for Ka = 0, 0.5, 1, 4 on the heavy stage with Kg-scaled
//! PID gains and the default shaping filter Ha (first order, 300 Hz), Table 7-3's force; and
//! the acceleration loop's stability on default settings.

use crate::common;

use common::plan;
use loop_model::closed_loop::{input, output};
use run_config::{ControllerKind, Loaded, Scenario};
use studies::intermittent::study;

fn cfg() -> Loaded {
    let mut c = Loaded::default();
    c.config.plant = plant_sim::params::PlantParams::heavy();
    c.config.scenario = Scenario::IntermittentCut {
        force_n: plant_sim::cutting::TABLE_7_3_FORCE_N,
        spindle_rpm: 250.0,
    };
    c.config.run.duration_s = 0.5;
    c.config.controller.kg_scaling = true;
    c
}

/// Peak |following error| of the sampled closed loop's response to a step of Table 7-3's force.
fn linear_peak(c: &Loaded) -> f64 {
    let cl = plan(c).closed_loop;
    let s = &cl.sys;
    let (b, cc) = (
        s.b.column(input::CUTTING_FORCE_N).into_owned(),
        s.c.row(output::FOLLOWING_ERROR_M).into_owned(),
    );
    let d = s.d[(output::FOLLOWING_ERROR_M, input::CUTTING_FORCE_N)];
    let mut x = nalgebra::DVector::zeros(s.nx());
    let mut peak = 0.0f64;
    for _ in 0..20_000 {
        peak = peak.max(((&cc * &x)[0] + d).abs());
        x = &s.a * &x + &b;
    }
    peak * plant_sim::cutting::TABLE_7_3_FORCE_N
}

/// §7.4.2 leaves Ha to the user "to maintain closed-loop stability": the default Ha keeps every
/// Ka of §7.5 stable with the fixed PID on both stages (Fig 7-13) and with Kg-scaled gains on
/// the heavy one (§7.6). Without Ha, Ka = 1 is unstable on the heavy stage.
#[test]
fn every_thesis_ka_is_stable_on_default_settings() {
    for (stage, kg) in [
        (plant_sim::params::StageParams::THESIS, false),
        (plant_sim::params::StageParams::THESIS_HEAVY, false),
        (plant_sim::params::StageParams::THESIS_HEAVY, true),
    ] {
        for ka in [0.0, 0.5, 1.0, 4.0] {
            let mut c = Loaded::default();
            c.config.plant.stage = stage;
            let k = &mut c.config.controller;
            (k.kind, k.ka, k.kg_scaling) = (ControllerKind::Accel, ka, kg);
            let radius = plan(&c).closed_loop.spectral_radius();
            assert!(radius < 1.0, "Ka {ka}, Kg {kg}, {stage:?}: {radius}");
        }
    }
    let mut bare = Loaded::default();
    bare.config.plant.stage = plant_sim::params::StageParams::THESIS_HEAVY;
    let k = &mut bare.config.controller;
    (k.kind, k.ka, k.accel_filter_hz) = (ControllerKind::Accel, 1.0, 0.0);
    assert!(plan(&bare).closed_loop.spectral_radius() > 1.0);
}

#[test]
fn stiffer_with_acceleration_feedback_as_the_thesis_measured() {
    let rows = study(&plan(&cfg()), &[0.0, 0.5, 1.0, 4.0]).unwrap();
    for w in rows.windows(2) {
        assert!(
            w[1].peak_following_error_m < w[0].peak_following_error_m,
            "{rows:?}"
        );
        assert!(w[1].edge_form_error_m < w[0].edge_form_error_m, "{rows:?}");
    }
    let (first, last) = (rows[0], rows[3]);
    // Thesis §7.6: peak following error 75 → 25 nm (3×), edge form error 106 → 27 nm (3.9×).
    assert!(first.peak_following_error_m > 3.0 * last.peak_following_error_m);
    assert!(first.edge_form_error_m > 3.9 * last.edge_form_error_m);
    // Each force step is answered as the linear sampled loop predicts. Noise adds a few nm to
    // the measured peaks (2 nm of 9 at Ka = 4), so this runs without it.
    let mut quiet = cfg();
    let n = &mut quiet.config.plant.noise;
    (n.sensor, n.current, n.base, n.accel) = (false, false, false, false);
    let quiet_rows = study(&plan(&quiet), &[0.0, 0.5, 1.0, 4.0]).unwrap();
    for r in &quiet_rows {
        let mut c = quiet.clone();
        c.config.controller.kind = ControllerKind::Accel;
        c.config.controller.ka = r.ka;
        let predicted = linear_peak(&c);
        assert!(
            (r.peak_following_error_m / predicted - 1.0).abs() < 0.1,
            "Ka {}: {} vs linear {predicted}",
            r.ka,
            r.peak_following_error_m
        );
    }
}
