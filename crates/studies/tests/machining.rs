//! Machining a sinusoidal grid (thesis §8.5.4, Table 8-5) in simulation: the machined
//! amplitude against the closed loop's analytic response, and what feedforward does to it.

use crate::common;

use common::{machine, plan};
use loop_model::closed_loop::{input, output};
use run_config::Machining;
use run_config::{FeedforwardKind, Loaded, Scenario};
use std::f64::consts::TAU;
use studies::form::FormReport;

/// Three revolutions inward from `outer_m` at 60 rpm with feedforward `ff`.
fn cfg(outer_m: f64, ff: FeedforwardKind) -> Loaded {
    let mut cfg = Loaded::default();
    let m = Machining {
        start_radius_m: outer_m,
        ..Machining::default()
    };
    cfg.config.run.duration_s = 3.0;
    cfg.config.run.settle_s = Some(0.05);
    cfg.config.scenario = Scenario::Machine(m);
    cfg.config.controller.feedforward = ff;
    cfg
}

fn machined(cfg: &Loaded) -> FormReport {
    machine(&plan(cfg)).1.report()
}

/// The X peak-to-valley the loop should machine without feedforward, from the analytic
/// closed loop alone: around the circle of radius r each grid term is a sinusoid of
/// instantaneous frequency `f = (1/2π)·dφ/dt` (φ = 2πx/λ, so `|f| ≤ r·ω/λ`), reproduced
/// quasi-statically with the loop's gain and phase at f (conjugate for f < 0); the tool
/// trajectory so predicted is fitted exactly as the machined one is.
fn predicted_pv_x(cfg: &Loaded, r: f64) -> f64 {
    let cl = plan(cfg).closed_loop;
    let t = |f: f64| {
        let h = cl
            .response(output::TOOL_M, input::REFERENCE_M, f.abs())
            .unwrap();
        if f < 0.0 {
            h.conj()
        } else {
            h
        }
    };
    let (omega, lambda, a) = (TAU, 1e-3, 5e-6);
    let mut ata = nalgebra::SMatrix::<f64, 5, 5>::zeros();
    let mut atb = nalgebra::SVector::<f64, 5>::zeros();
    let n = 200_000;
    for i in 0..n {
        let theta = (i as f64 + 0.5) * TAU / n as f64;
        let (px, py) = (
            TAU * r * libm::cos(theta) / lambda,
            TAU * r * libm::sin(theta) / lambda,
        );
        let (fx, fy) = (
            -r * omega * libm::sin(theta) / lambda,
            r * omega * libm::cos(theta) / lambda,
        );
        let term = |p: f64, f: f64| {
            let h = t(f);
            a * h.norm() * libm::sin(p + h.arg())
        };
        let tool = term(px, fx) + term(py, fy);
        let b = nalgebra::SVector::<f64, 5>::from([
            libm::sin(px),
            libm::cos(px),
            libm::sin(py),
            libm::cos(py),
            1.0,
        ]);
        ata += b * b.transpose();
        atb += b * tool;
    }
    let c = ata.try_inverse().unwrap() * atb;
    2.0 * libm::hypot(c[0], c[1])
}

#[test]
fn edge_of_the_part_overcuts_as_the_loop_gain_predicts_and_zpetc_removes_it() {
    let edge = run_config::GRID_EDGE_RADIUS_M;
    let plain = cfg(edge, FeedforwardKind::None);
    let none = machined(&plain);
    let grid = none.grid.unwrap();
    // The thesis measured 11.18 µm for a 10 µm grid at the edge (§8.5.4): the loop's |T| > 1
    // below its resonance magnifies the motion. Here: the analytic loop's mean gain.
    let predicted = predicted_pv_x(&plain, edge);
    assert!(grid.machined_pv_x_m > 10.1e-6, "{:?}", grid);
    assert!(
        (grid.machined_pv_x_m - predicted).abs() < 0.05 * (predicted - 10e-6),
        "machined {} vs predicted {predicted}",
        grid.machined_pv_x_m
    );
    // §8.5.4: "about 200 Hz at the edge".
    assert!((none.max_motion_frequency_hz.unwrap() - 200.0).abs() < 0.1);

    let zpetc = machined(&cfg(edge, FeedforwardKind::Zpetc));
    let g = zpetc.grid.unwrap();
    assert!((g.machined_pv_x_m / 10e-6 - 1.0).abs() < 0.01, "{g:?}");
    assert!((g.machined_pv_y_m / 10e-6 - 1.0).abs() < 0.01, "{g:?}");
    assert!(
        zpetc.form_error_m.rms < none.form_error_m.rms / 10.0,
        "form RMS {} vs {}",
        zpetc.form_error_m.rms,
        none.form_error_m.rms
    );

    // Inverting the loop to the sensor instead: the sensor follows the surface, and what is
    // left of its following error is the noise floor of a loop holding still (0.88 nm RMS in
    // the default hold run; thesis §5.7.4: 0.83 nm) — a tick of misalignment would leave
    // 2π · 200 Hz · 5 µm · 5.01 µs / √2 = 22 nm.
    let sensor = machined(&cfg(edge, FeedforwardKind::ZpetcSensor));
    assert!(
        sensor.following_error_m.rms < 1.5e-9,
        "following RMS {} vs {}",
        sensor.following_error_m.rms,
        none.following_error_m.rms
    );
    // The sensor lags the tool: aiming the tool at the surface shows that lag as following
    // error, aiming the sensor leaves the same lag as form error.
    let lag_as_following = zpetc.following_error_m.rms;
    let lag_as_form = sensor.form_error_m.rms;
    assert!(
        (lag_as_following / lag_as_form - 1.0).abs() < 0.05,
        "{lag_as_following} vs {lag_as_form}"
    );
}

#[test]
fn near_the_centre_the_slow_motion_is_machined_true() {
    // 2.5 mm from the axis the grid moves the tool at ≤ 16 Hz (thesis: 10.02 µm at the centre).
    let centre = machined(&cfg(2.5e-3, FeedforwardKind::None));
    let g = centre.grid.unwrap();
    assert!((g.machined_pv_x_m / 10e-6 - 1.0).abs() < 0.005, "{g:?}");
}

#[test]
fn beam_integrator_transition_overshoot_shrinks_with_smoothed_zpetc() {
    // Table 8-4 at the part edge, 120 rpm. The cell edges are kinks (the slope flips from +L/2R
    // to −L/2R): the loop overshoots them (thesis Fig 8-15: ≈ 0.4 µm); the exact inverse of the
    // loop would ask the DAC for more than it has, so ZPETC runs on a 5 kHz zero-phase
    // smoothed trajectory.
    let beam = |ff: FeedforwardKind, smoothing_hz: f64| {
        let mut c = cfg(25e-3, ff);
        if let Scenario::Machine(m) = &mut c.config.scenario {
            m.surface = run_config::SurfaceConfig::THESIS_BEAM;
            m.spindle_rpm = 120.0;
        }
        c.config.run.duration_s = 1.0;
        c.config.controller.smoothing_hz = smoothing_hz;
        machined(&c)
    };
    let none = beam(FeedforwardKind::None, 0.0);
    assert!(
        (0.2e-6..2e-6).contains(&none.max_abs_form_error_m),
        "{}",
        none.max_abs_form_error_m
    );
    let zpetc = beam(FeedforwardKind::Zpetc, 5000.0);
    assert!(
        zpetc.max_abs_form_error_m < none.max_abs_form_error_m / 4.0,
        "{} vs {}",
        zpetc.max_abs_form_error_m,
        none.max_abs_form_error_m
    );
}
