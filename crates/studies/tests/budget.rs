//! The error budget (frequency domain, eq 5-13..5-17) against long seeded time-domain runs.

use crate::common;

use common::plan;
use run_config::{Loaded, PidGains};
use runner::run::run_to_end;
use studies::budget::Budget;

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

/// The budget's CAS at Nyquist (eq 5-16, integrated on its log grid) is the exact (Lyapunov)
/// RMS to the grid's accuracy; its totals against long simulations: `tests/budget_exact.rs`.
#[test]
fn cas_at_nyquist_is_the_exact_rms() {
    let cl = plan(&heavy_468()).closed_loop;
    let b = Budget::new(&cl, 2000).unwrap();
    for c in &b.contributions {
        println!(
            "  {:>13}: {:.3} / {:.3} nm",
            c.source,
            c.following_rms_m * 1e9,
            c.true_rms_m * 1e9
        );
    }
    assert!((b.following_cas.last().unwrap() / b.following_rms_m - 1.0).abs() < 0.02);
}

/// Fig 5-14 style sweep for both masses: at every bandwidth the budget's RMS following and
/// true errors agree with 2 s seeded simulations within 5 % (the scatter of a 2 s run is
/// ≈ 2 %).
#[test]
fn sweep_predictions_match_simulation_for_both_masses() {
    let sweeps = studies::sweep::thesis_sweeps(
        &plan(&heavy_468()),
        &[300.0, 468.0, 700.0, 874.0, 1200.0],
        studies::sweep::SweepTuning::Scaled,
        Some(2.0),
        &mut |_, _| {},
    )
    .unwrap();
    for s in &sweeps {
        let label = &s.label;
        println!("{label}: unreached {:?}", s.unreached);
        // The light stage's |T| dips below −3 dB at the m4 mode (≈ 422 Hz) until the gain
        // lifts the dip, so its first −3 dB crossing jumps from below 468 Hz to ≈ 575 Hz: 468 Hz
        // is not a bandwidth any scaling of the PID has. Every other target is reached.
        let unreached: Vec<f64> = s.unreached.iter().map(|u| u.0).collect();
        let want: &[f64] = if label.starts_with("0.074") {
            &[468.0]
        } else {
            &[]
        };
        assert_eq!(unreached, want, "{label}");
        for p in &s.points {
            let (sf, st) = (
                p.simulated_following_m.unwrap(),
                p.simulated_true_m.unwrap(),
            );
            println!(
                "{label} {:>7.1} Hz: following {:.3} vs {:.3} nm, true {:.3} vs {:.3} nm",
                p.bandwidth_hz,
                p.predicted_following_m * 1e9,
                sf * 1e9,
                p.predicted_true_m * 1e9,
                st * 1e9
            );
            assert!((p.bandwidth_hz / p.target_hz - 1.0).abs() < 0.01);
            assert!(
                (p.predicted_following_m / sf - 1.0).abs() < 0.05,
                "{label} at {} Hz",
                p.target_hz
            );
            assert!(
                (p.predicted_true_m / st - 1.0).abs() < 0.05,
                "{label} at {} Hz",
                p.target_hz
            );
        }
        println!(
            "{label}: predicted optimum following {}, true {}",
            s.optimum_following.describe(),
            s.optimum_true.describe()
        );
    }
}

/// Stepped-sine FRFs on the running simulator (all noise on) agree with the model of the
/// sampled loop within 0.5 dB and 3° wherever the coherence exceeds 0.99, open and closed loop.
#[test]
fn stepped_sine_frf_matches_the_model() {
    use studies::frf::{stepped_sine, FrfLoop, FrfSettings};
    let cfg = Loaded::default();
    let freqs = [
        20.0, 82.0, 200.0, 420.0, 1000.0, 1645.0, 3000.0, 7748.0, 15000.0,
    ];
    for which in [FrfLoop::Open, FrfLoop::Closed] {
        let pts = stepped_sine(
            &plan(&cfg),
            which,
            &freqs,
            &FrfSettings::for_loop(which),
            &mut |_, _| {},
        )
        .unwrap();
        let mut good = 0;
        for p in &pts {
            println!(
                "{which:?} {:>8.1} Hz: {:+.3} dB {:+.2}° γ² {:.5}",
                p.freq_hz,
                p.error_db(),
                p.error_deg(),
                p.coherence
            );
            assert!(!p.clipped, "{which:?} at {} Hz clipped", p.freq_hz);
            if p.coherence > 0.99 {
                good += 1;
                assert!(
                    p.error_db().abs() < 0.5 && p.error_deg().abs() < 3.0,
                    "{which:?} at {} Hz",
                    p.freq_hz
                );
            }
        }
        assert!(good >= 6, "{which:?}: only {good} coherent points");
    }
}

/// Eq 7-9 (generalised to the impedance model) against the simulator's sampled loop: within
/// 1 dB up to 10 kHz for Ka ∈ {0, 0.5, 1, 4}, fixed and Kg-scaled PID (as frequency functions;
/// the loops that are unstable with the default accelerometer chain are reported as such);
/// with Kg scaling the servo's low-frequency stiffness (at m2: the tool shank's 1/k1 is in
/// series outside the loop) rises in proportion to the PID gain factor (§7.4.1).
#[test]
fn compliance_analytic_matches_sampled_loop() {
    use studies::stiffness::compliance;
    let cfg = Loaded::default();
    let freqs: Vec<f64> = (0..60)
        .map(|i| 10f64 * libm::pow(1000f64, i as f64 / 59.0))
        .collect(); // 10 Hz … 10 kHz
    for kg in [false, true] {
        let curves = compliance(&plan(&cfg), &[0.0, 0.5, 1.0, 4.0], kg, &freqs).unwrap();
        for c in &curves {
            let worst = c
                .analytic_m_per_n
                .iter()
                .zip(&c.sampled_m_per_n)
                .map(|(a, s)| (20.0 * libm::log10(a / s)).abs())
                .fold(0.0, f64::max);
            println!("Ka {} (PID ×{:.3}, spectral radius {:.6}): worst |analytic − sampled| {worst:.3} dB", c.ka, c.pid_scale, c.spectral_radius);
            assert!(worst < 1.0, "Ka {} kg {kg}: {worst} dB", c.ka);
        }
        assert!(curves[0].stable(), "the Ch7 PID alone is stable");
    }
    // Kg scaling on the heavy stage, where Ka = 0.5 is stable: at 10 Hz the integral term
    // dominates the servo stiffness, so it rises by the gain factor (1 %).
    let mut heavy = Loaded::default();
    heavy.config.plant = plant_sim::PlantParams::heavy();
    let curves = compliance(&plan(&heavy), &[0.0, 0.5], true, &[10.0]).unwrap();
    assert!(curves[1].stable());
    let ratio = curves[0].sampled_m2_m_per_n[0] / curves[1].sampled_m2_m_per_n[0];
    assert!(
        (ratio / curves[1].pid_scale - 1.0).abs() < 0.01,
        "stiffness ×{ratio:.4} vs gains ×{:.4}",
        curves[1].pid_scale
    );
    {}
}

/// The chirp + Welch H1 path: closed loop, the model within 0.5 dB and 3° wherever coherence
/// exceeds 0.99 (most bins between 20 Hz and 5 kHz), or within five times the estimate's own
/// random error where that is larger: an H1 estimate over n_d averages at coherence γ² scatters
/// by ε = √(1 − γ²)/(|γ|·√(2 n_d)) in relative magnitude and in radians of phase (Bendat &
/// Piersol, Random Data, §9.2.4) — at γ² = 0.99 and 16 sweeps 1.0° (1σ), so a fixed 3° failed
/// by chance on some noise draws.
#[test]
fn chirp_frf_matches_the_model() {
    use studies::frf::{chirp, FrfLoop};
    let sweeps = 16;
    let pts = chirp(
        &plan(&Loaded::default()),
        FrfLoop::Closed,
        (20.0, 5000.0),
        0.2,
        0.2,
        sweeps,
    )
    .unwrap();
    let good: Vec<_> = pts.iter().filter(|p| p.coherence > 0.99).collect();
    assert!(
        good.len() * 10 >= pts.len() * 8,
        "{} of {} bins coherent",
        good.len(),
        pts.len()
    );
    for p in good {
        let eps = (1.0 - p.coherence).sqrt() / (p.coherence.sqrt() * (2.0 * sweeps as f64).sqrt());
        let (db, deg) = (
            0.5f64.max(5.0 * 20.0 * libm::log10(1.0 + eps)),
            3.0f64.max(5.0 * eps.to_degrees()),
        );
        assert!(
            p.error_db().abs() < db && p.error_deg().abs() < deg,
            "{} Hz: {:.3} dB {:.2}° (coherence {:.4}: bounds {db:.2} dB {deg:.2}°)",
            p.freq_hz,
            p.error_db(),
            p.error_deg(),
            p.coherence
        );
    }
}

/// Fig 5-14 the thesis's way (§5.7.3: gains re-tuned for each crossover): the predicted
/// following error has an interior optimum for both masses, and the heavier stage's lies at
/// the lower bandwidth (thesis: 874 Hz for 0.074 kg, 468 Hz for 0.174 kg).
#[test]
fn retuned_sweep_has_an_optimum_that_falls_with_mass() {
    let crossovers = [
        200.0, 300.0, 400.0, 468.0, 550.0, 650.0, 750.0, 874.0, 1000.0, 1450.0,
    ];
    let sweeps = studies::sweep::thesis_sweeps(
        &plan(&heavy_468()),
        &crossovers,
        studies::sweep::SweepTuning::Retuned,
        None,
        &mut |_, _| {},
    )
    .unwrap();
    let mut optima = Vec::new();
    for s in &sweeps {
        let label = &s.label;
        assert!(s.unreached.is_empty(), "{label}: {:?}", s.unreached);
        let f: Vec<f64> = s.points.iter().map(|p| p.predicted_following_m).collect();
        let best = f.iter().copied().fold(f64::MAX, f64::min);
        println!(
            "{label}: optimum {}; ends {:.3} / {:.3} nm",
            s.optimum_following.describe(),
            f[0] * 1e9,
            f[f.len() - 1] * 1e9
        );
        // Interior: both ends of the sweep are worse than the optimum by more than 1 %.
        assert!(
            f[0] > 1.01 * best && f[f.len() - 1] > 1.01 * best,
            "{label}"
        );
        optima.push(s.optimum_following.bandwidth_hz);
    }
    assert!(optima[1] < optima[0], "optima {optima:?}");
}

/// Thesis §6.4.2: the H2 controller at 20 kHz beats a PID at the same rate and a similar
/// bandwidth in true RMS positioning error, on the simulator (long seeded runs).
#[test]
fn h2_at_20_khz_beats_the_pid() {
    use studies::synth::h2_design;
    let mut base = Loaded::default();
    base.config.plant = plant_sim::PlantParams::heavy();
    base.config.plant.noise.accel = false;
    base.config.plant.timing.servo_rate_hz = 20_000.0;
    base.config.run.duration_s = 3.0;
    let design = h2_design(&plan(&base), 1.0).unwrap();
    assert!(design.spectral_radius < 1.0);
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("h2.toml");
    std::fs::write(&file, design.to_toml()).unwrap();
    let mut h2 = base.clone();
    h2.config.controller.kind = run_config::ControllerKind::Ss;
    h2.config.controller.ss_file = Some(file);
    let cl = plan(&h2).closed_loop;
    let bw = cl.bandwidth_hz().unwrap();
    let run_it = |cfg: &Loaded| run_to_end(&plan(cfg)).unwrap();
    let h2_run = run_it(&h2);
    println!(
        "H2: bandwidth {bw:.0} Hz, true {:.3} nm, following {:.3} nm",
        h2_run.true_error_m.rms * 1e9,
        h2_run.following_error_m.rms * 1e9
    );
    // The PID scaled to the same bandwidth at 20 kHz, or as close as a stable PID gets.
    let reachable = [1.0, 0.9, 0.8, 0.7, 0.6, 0.5, 0.4]
        .iter()
        .find_map(|f| studies::sweep::scale_for_bandwidth(&plan(&base), bw * f).unwrap());
    let (scale, pid_bw) = reachable.expect("a stable PID near that bandwidth");
    let mut pid = base.clone();
    let p = &mut pid.config.controller.pid;
    (p.kp, p.ki, p.kd) = (p.kp * scale, p.ki * scale, p.kd * scale);
    let pid_run = run_it(&pid);
    println!(
        "H2 ({} states, bw {bw:.0} Hz): following {:.3} nm, true {:.3} nm; PID (bw {pid_bw:.0} Hz): following {:.3} nm, true {:.3} nm",
        design.controller.nx(),
        h2_run.following_error_m.rms * 1e9,
        h2_run.true_error_m.rms * 1e9,
        pid_run.following_error_m.rms * 1e9,
        pid_run.true_error_m.rms * 1e9
    );
    assert!(h2_run.true_error_m.rms < pid_run.true_error_m.rms);
    // Table 6-1 orders: the balanced-truncated 13- and 8-state controllers still stabilise the
    // loop and lose less than 5 % of the predicted true RMS error.
    let full_true = studies::budget::Budget::new(&cl, 64).unwrap().true_rms_m;
    for order in [13, 8] {
        let (reduced, _, _) = design.reduced(order).unwrap();
        let f = dir.path().join(format!("h2_{order}.toml"));
        std::fs::write(&f, reduced.to_toml()).unwrap();
        let mut r = h2.clone();
        r.config.controller.ss_file = Some(f);
        let rcl = plan(&r).closed_loop;
        assert!(rcl.spectral_radius() < 1.0, "order {order} destabilises");
        let t = studies::budget::Budget::new(&rcl, 64).unwrap().true_rms_m;
        assert!(
            t / full_true - 1.0 < 0.05,
            "order {order}: {t:e} vs {full_true:e}"
        );
    }
}

/// The gain margins of the sampled loop predict the eigenvalues: the PID scaled to 98 % of its
/// (upper) gain margin is stable, to 102 % unstable; the loop is conditionally stable (the
/// −180° crossing at the suspension resonance), and its lower margin is exact the same way.
#[test]
fn gain_margin_predicts_the_stability_limit() {
    let cfg = Loaded::default();
    let m = studies::margins::loop_margins(&plan(&cfg)).unwrap();
    let gm = m.gain_margin_db.expect("a phase crossover below Nyquist");
    let pm = m.phase_margin_deg.expect("a gain crossover");
    let lower = m
        .lower_gain_margin_db
        .expect("conditionally stable: the suspension resonance");
    println!(
        "Ch7 PID, light stage: crossover {:.0} Hz, PM {pm:.1}°, GM {gm:.2} dB at {:.0} Hz, lower GM {lower:.2} dB",
        m.gain_crossover_hz.unwrap(),
        m.phase_crossover_hz.unwrap()
    );
    assert!(pm > 0.0 && gm > 0.0 && lower < 0.0);
    let (up, down) = (libm::pow(10f64, gm / 20.0), libm::pow(10f64, lower / 20.0));
    for (k, stable) in [
        (0.98 * up, true),
        (1.02 * up, false),
        (1.02 * down, true),
        (0.98 * down, false),
    ] {
        let mut c = cfg.clone();
        let p = &mut c.config.controller.pid;
        (p.kp, p.ki, p.kd) = (p.kp * k, p.ki * k, p.kd * k);
        let cl = plan(&c).closed_loop;
        assert_eq!(
            cl.spectral_radius() < 1.0,
            stable,
            "×{k:.3}: radius {}",
            cl.spectral_radius()
        );
    }
}

/// The range `servo ctl gain` checks against (bisection on the sampled loop's eigenvalues)
/// is the loop's frequency-domain gain margins, upper and lower, to 1e-3; a change keeps 6 dB.
#[test]
fn the_ctl_gain_range_is_the_loops_gain_margins() {
    let cfg = Loaded::default();
    let p = plan(&cfg);
    let m = studies::margins::loop_margins(&p).unwrap();
    let (up, down) = (
        libm::pow(10f64, m.gain_margin_db.unwrap() / 20.0),
        libm::pow(10f64, m.lower_gain_margin_db.unwrap() / 20.0),
    );
    let r = runner::gain_range::gain_range(&p).unwrap();
    assert!(
        (r.unstable_above / up - 1.0).abs() < 1e-3,
        "{} vs {up}",
        r.unstable_above
    );
    assert!(
        (r.unstable_below / down - 1.0).abs() < 1e-3,
        "{} vs {down}",
        r.unstable_below
    );
    // The issue's `ctl gain 10` is refused, the 6 dB-safe range is allowed.
    assert!(!r.allows(10.0) && !r.allows(0.99 * up) && !r.allows(f64::NAN));
    assert!(r.allows(1.0) && r.allows(0.999 * up / 2.0) && r.allows(1.001 * 2.0 * down));
}

/// Thesis eq 6-4: Ms = 1.2721 for ξ = 0.707 (§6.3.1).
#[test]
fn ms_of_eq_6_4_is_the_thesis_value() {
    let ms = studies::synth::ms_for_damping(0.707);
    assert!((ms - 1.2721).abs() < 5e-5, "Ms {ms}"); // thesis: 1.2721
}

/// The thesis §6.3 weighting (We, Wu, Ws, Wi, Wg, Wfc) at 20 kHz on the heavy stage: the design
/// stabilises the exact sampled loop (delay, hold, ADC averaging) it runs in, with a
/// loop-gain crossover near the thesis's 870 Hz (§6.3.2), and gentler effort weights give lower
/// bandwidth.
#[test]
fn thesis_weighted_h2_stabilises_the_exact_loop() {
    let mut cfg = heavy_468();
    cfg.config.plant.timing.servo_rate_hz = 20_000.0;
    let dir = tempfile::tempdir().unwrap();
    let mut bandwidths = Vec::new();
    for effort in [1e3, 1e4] {
        let d = studies::synth::thesis_design(&plan(&cfg), &Default::default(), effort).unwrap();
        let f = dir.path().join(format!("thesis_{effort}.toml"));
        std::fs::write(&f, d.to_toml()).unwrap();
        let mut run_cfg = cfg.clone();
        run_cfg.config.controller.kind = run_config::ControllerKind::Ss;
        run_cfg.config.controller.ss_file = Some(f);
        let cl = plan(&run_cfg).closed_loop;
        assert!(cl.spectral_radius() < 1.0, "ρ {effort}: unstable");
        let m = studies::margins::loop_margins(&plan(&run_cfg)).unwrap();
        bandwidths.push(Budget::new(&cl, 64).unwrap().bandwidth_hz);
        if effort == 1e3 {
            let crossover = m.gain_crossover_hz.unwrap_or(f64::NAN);
            assert!(
                (500.0..2000.0).contains(&crossover),
                "crossover {crossover} Hz (thesis 870 Hz)"
            );
        }
    }
    assert!(bandwidths[1] < bandwidths[0], "{bandwidths:?}");
}

/// With acceleration feedback the loop broken at the actuator input includes the inner
/// acceleration path: the whole controller (PID and Ka, §7.4) scaled to 98 % of the upper gain
/// margin is stable, to 102 % unstable — on the heavy stage at Ka = 1 with the PID × 3, where
/// the margins of the gap channel alone say something else.
#[test]
fn gain_margin_with_acceleration_feedback_predicts_the_stability_limit() {
    let mut cfg = heavy_468();
    let c = &mut cfg.config.controller;
    c.kind = run_config::ControllerKind::Accel;
    c.pid = PidGains {
        kp: c.pid.kp * 3.0,
        ki: c.pid.ki * 3.0,
        kd: c.pid.kd * 3.0,
        ..c.pid
    };
    c.ka = 1.0;
    let m = studies::margins::loop_margins(&plan(&cfg)).unwrap();
    let gm = m.gain_margin_db.expect("a phase crossover below Nyquist");
    println!(
        "Ka 1, PID ×3, heavy: crossover {:.0} Hz, PM {:.1}°, GM {gm:.2} dB at {:.0} Hz",
        m.gain_crossover_hz.unwrap_or(f64::NAN),
        m.phase_margin_deg.unwrap_or(f64::NAN),
        m.phase_crossover_hz.unwrap_or(f64::NAN)
    );
    let up = libm::pow(10f64, gm / 20.0);
    for (k, stable) in [(0.98 * up, true), (1.02 * up, false)] {
        let mut s = cfg.clone();
        let c = &mut s.config.controller;
        (c.pid.kp, c.pid.ki, c.pid.kd, c.ka) = (c.pid.kp * k, c.pid.ki * k, c.pid.kd * k, c.ka * k);
        let cl = plan(&s).closed_loop;
        assert_eq!(
            cl.spectral_radius() < 1.0,
            stable,
            "×{k:.3}: radius {}",
            cl.spectral_radius()
        );
    }
}
