//! The intermittent cut of thesis §7.6 for Ka = 0, 0.5, 1, 4 on the heavy stage with Kg-scaled
//! PID gains and a first-order 300 Hz acceleration shaping filter.

mod common;

use common::plan;
use runner::closed_loop::{input, output};
use runner::config::{ControllerKind, Loaded, Scenario};
use studies::intermittent::study;

fn cfg() -> Loaded {
    let mut c = Loaded::default();
    c.config.plant = plant_sim::params::PlantParams::heavy();
    c.config.scenario = Scenario::IntermittentCut {
        force_n: 1.0,
        spindle_rpm: 250.0,
    };
    c.config.run.duration_s = 0.5;
    let k = &mut c.config.controller;
    k.kg_scaling = true;
    k.accel_filter_hz = 300.0;
    k.accel_filter_order = 1;
    c
}

/// Peak |following error| of the sampled closed loop's response to a force step of 1 N.
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
    peak
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
    // Each force step is answered as the linear sampled loop predicts (noise adds a few nm).
    for r in &rows {
        let mut c = cfg();
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
