//! The budget's totals against long seeded simulations within 0.5 %, on both stages at 199.6
//! and 20 kHz, and with the sensor channel's first-order anti-aliasing stage at 30 kHz (all
//! default disturbances but the accelerometer, default converters). Each
//! simulation is long enough that its own scatter — the standard error of an RMS estimated
//! from a record of length T, `½·√(∫G²df / T) / ∫G df` for a Gaussian signal of one-sided PSD
//! G, here the budget's own PSD — is below a third of the tolerance, so a 0.5 % disagreement is
//! a model error, not chance; the seeds are fixed (the run's default seed).

use crate::common;

use common::plan;
use run_config::Loaded;
use runner::run::run_to_end;
use studies::budget::{total_psd, Budget};

/// Standard error (relative) of the RMS of a record of `duration_s` of a Gaussian signal
/// with one-sided PSD `psd` on `freq_hz`.
fn rms_scatter(freq_hz: &[f64], psd: &[f64], duration_s: f64) -> f64 {
    let (mut power, mut square) = (0.0, 0.0);
    for i in 1..freq_hz.len() {
        let df = freq_hz[i] - freq_hz[i - 1];
        power += 0.5 * (psd[i] + psd[i - 1]) * df;
        square += 0.5 * (psd[i] * psd[i] + psd[i - 1] * psd[i - 1]) * df;
    }
    0.5 * (square / duration_s).sqrt() / power
}

/// The loop of a stage at a rate with its PID scaled to `bandwidth_hz` at 199.6 kHz.
fn case(stage: plant_sim::params::StageParams, rate_hz: f64, bandwidth_hz: f64) -> Loaded {
    let mut l = Loaded::default();
    let c = &mut l.config;
    c.plant.stage = stage;
    c.plant.noise.accel = false;
    let (k, _) = studies::sweep::scale_for_bandwidth(&plan(&l), bandwidth_hz)
        .unwrap()
        .unwrap();
    let p = &mut l.config.controller.pid;
    (p.kp, p.ki, p.kd) = (p.kp * k, p.ki * k, p.kd * k);
    l.config.plant.timing.servo_rate_hz = rate_hz;
    l
}

#[test]
fn budget_totals_equal_long_simulations_within_half_a_percent() {
    use plant_sim::params::StageParams;
    for (label, stage, rate, bw, duration, anti_alias_hz) in [
        (
            "0.174 kg, 199.6 kHz",
            StageParams::THESIS_HEAVY,
            199.6e3,
            468.0,
            200.0,
            0.0,
        ),
        (
            "0.174 kg, 199.6 kHz, 30 kHz anti-aliasing stage",
            StageParams::THESIS_HEAVY,
            199.6e3,
            468.0,
            200.0,
            30e3,
        ),
        (
            "0.074 kg, 199.6 kHz",
            StageParams::THESIS,
            199.6e3,
            700.0,
            200.0,
            0.0,
        ),
        (
            "0.174 kg, 20 kHz",
            StageParams::THESIS_HEAVY,
            20e3,
            468.0,
            400.0,
            0.0,
        ),
        (
            "0.074 kg, 20 kHz",
            StageParams::THESIS,
            20e3,
            700.0,
            400.0,
            0.0,
        ),
    ] {
        let mut l = case(stage, rate, bw);
        l.config.run.duration_s = duration;
        l.config.plant.adc.anti_alias_hz = anti_alias_hz;
        let p = plan(&l);
        let b = Budget::new(&p.closed_loop, 4000).unwrap();
        let s = run_to_end(&p).unwrap();
        let settled = duration - l.config.run.settle();
        for (what, predicted, simulated, psd) in [
            (
                "following",
                b.following_rms_m,
                s.following_error_m.rms,
                &b.following_psd,
            ),
            ("true", b.true_rms_m, s.true_error_m.rms, &b.true_psd),
        ] {
            let scatter = rms_scatter(&b.freq_hz, &total_psd(psd), settled);
            let miss = simulated / predicted - 1.0;
            println!(
                "{label}: {what} predicted {:.4} nm, simulated {:.4} nm ({:+.3} %, scatter {:.3} %; {settled} s, seed {})",
                predicted * 1e9,
                simulated * 1e9,
                miss * 100.0,
                scatter * 100.0,
                l.config.run.seed
            );
            assert!(
                scatter < 0.005 / 3.0,
                "{label} {what}: the run is too short to judge 0.5 %"
            );
            assert!(miss.abs() < 0.005, "{label} {what}: {:+.3} %", miss * 100.0);
        }
    }
}
