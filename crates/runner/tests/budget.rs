//! The error budget (frequency domain, eq 5-13..5-17) against long seeded time-domain runs.

use runner::analysis::Budget;
use runner::config::Loaded;
use runner::run::{closed_loop, run, RunOptions};
use std::sync::atomic::AtomicBool;

fn heavy_468() -> Loaded {
    let mut l = Loaded::default();
    let c = &mut l.config;
    c.plant = plant_sim::PlantParams::heavy();
    c.plant.noise.accel = false;
    c.controller.pid.kp = 0.6443;
    c.controller.pid.ki = 219.46;
    c.controller.pid.kd = 3.7097e-4;
    c.run.duration_s = 3.0;
    l
}

#[test]
fn budget_predicts_the_simulated_errors() {
    let cfg = heavy_468();
    let (cl, _) = closed_loop(&cfg).unwrap();
    let b = Budget::new(&cl, 2000).unwrap();
    let stop = AtomicBool::new(false);
    let s = run(
        &cfg,
        RunOptions {
            out: None,
            stop: &stop,
            progress: &mut |_, _| {},
        },
    )
    .unwrap();
    let (pf, pt) = (b.following_rms_m * 1e9, b.true_rms_m * 1e9);
    let (sf, st) = (s.following_error_m.rms * 1e9, s.true_error_m.rms * 1e9);
    println!(
        "bandwidth {:.1} Hz; predicted {pf:.3}/{pt:.3} nm, simulated {sf:.3}/{st:.3} nm",
        b.bandwidth_hz
    );
    for c in &b.contributions {
        println!(
            "  {:>13}: {:.3} / {:.3} nm",
            c.source,
            c.following_rms_m * 1e9,
            c.true_rms_m * 1e9
        );
    }
    assert!((pf / sf - 1.0).abs() < 0.10);
    assert!((pt / st - 1.0).abs() < 0.10);
    // CAS at Nyquist agrees with the exact (Lyapunov) RMS to the grid's accuracy.
    assert!((b.following_cas.last().unwrap() / b.following_rms_m - 1.0).abs() < 0.02);
}
