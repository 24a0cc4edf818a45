//! The recorded following error is the controller's: each tick's reference with the reading it
//! acted on. On a 200 Hz, 5 µm sine (noise off) it equals the analytic sampled closed loop's
//! error, `S(e^{jωT})·r`, within 0.5 % in amplitude and phase — which the pairing with the next
//! reading (contract v5) missed by ωT·|r|/|e| ≈ 3 %.

use loop_model::closed_loop::{input, output};
use run_config::{Loaded, Scenario};
use runner::run::run_to_end_with;
use runner::Plan;

#[test]
fn the_recorded_following_error_of_a_sine_is_the_closed_loops() {
    let (amplitude, f_hz) = (5e-6, 200.0);
    let mut l = Loaded::default();
    l.config.run.duration_s = 0.2;
    l.config.scenario = Scenario::Sine {
        amplitude_m: amplitude,
        frequency_hz: f_hz,
    };
    let n = &mut l.config.plant.noise;
    (n.sensor, n.current, n.base, n.accel) = (false, false, false, false);
    let plan = Plan::new(&l).unwrap();
    let s = plan
        .closed_loop
        .response(output::FOLLOWING_ERROR_M, input::REFERENCE_M, f_hz)
        .unwrap();
    let mut frames = Vec::new();
    run_to_end_with(&plan, |f| frames.push(*f)).unwrap();
    // Least squares of e_k = a·cos(ωkT) + b·sin(ωkT) over the last 0.1 s (20 periods, the
    // loop's transients long gone); r_k = A·sin(ωkT) gives e_k = A·(Re S·sin + Im S·cos).
    let period = plan.period_s();
    let w = std::f64::consts::TAU * f_hz;
    let fit = |error: &dyn Fn(usize) -> f64| {
        let (mut cc, mut ss, mut cs, mut ec, mut es) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for k in frames.len() / 2..frames.len() - 1 {
            let (c, s) = (
                libm::cos(w * k as f64 * period),
                libm::sin(w * k as f64 * period),
            );
            let e = error(k);
            (cc, ss, cs, ec, es) = (cc + c * c, ss + s * s, cs + c * s, ec + e * c, es + e * s);
        }
        let det = cc * ss - cs * cs;
        let (a, b) = ((ec * ss - es * cs) / det, (es * cc - ec * cs) / det);
        num_complex::Complex64::new(b, a)
    };
    let want = num_complex::Complex64::new(amplitude * s.re, amplitude * s.im);
    let got = fit(&|k| f64::from(frames[k].telemetry.following_error_m));
    let off = (got - want).norm() / want.norm();
    assert!(
        off < 0.005,
        "recorded {got:.4e}, analytic {want:.4e} ({:.3} %)",
        100.0 * off
    );
    // The pairing with the next reading (contract v5) is a tick's motion away from it.
    let next = fit(&|k| {
        f64::from(frames[k].telemetry.reference_m) - f64::from(frames[k + 1].telemetry.measured_m)
    });
    assert!((next - want).norm() / want.norm() > 0.01);
    // And the record's own arithmetic: following = reference − measured.
    let f = frames[frames.len() - 1].telemetry;
    assert!((f.reference_m - f.measured_m - f.following_error_m).abs() < 1e-12);
}
