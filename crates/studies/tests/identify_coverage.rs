//! The identified parameters' stated uncertainty means what it says: over 30 practice stages
//! (seeds 2000–2029: ±15 % draws of Table 5-2, a sensor-mount resonance at 5–9 kHz and a stage
//! mode at 1.2–2 kHz the four-mass model lacks; no drift, so that the drawn k2 is the truth),
//! each measured open loop by stepped sine (150 points, 20 Hz – 5 kHz)
//! and identified, the drawn values lie within the stated 1σ at 60–76 % of the 180
//! parameters (68 % expected) and within 2σ at ≥ 90 % (95 %): 66.7 % and 93.3 %. Both extra
//! modes are found on every stage — the mount above the band by its tail, within 5 % of its
//! drawn frequency (3.0 % at worst, a mount at 8.5 kHz) — so every residual is white and the
//! 1σ is the noise's. Five minutes, so not in the default run:
//! `cargo test --release -p studies --test integration identify_coverage -- --ignored
//! --nocapture`.

use crate::common;
use num_complex::Complex64;
use plant_sim::practice::PracticeDraw;
use run_config::Loaded;

#[test]
#[ignore = "five minutes: 30 stepped-sine measurements"]
fn the_stated_uncertainty_holds_the_drawn_values_at_its_rate() {
    let freqs = lti::spectral::log_space(20.0, 5000.0, 150);
    let model = common::plan(&Loaded::default());
    let (mut within_1, mut within_2, mut values) = (0, 0, 0);
    for seed in 2000..2030u64 {
        let mut practice = Loaded::default();
        practice.config.run.practice_seed = Some(seed);
        practice.config.run.practice_effects = common::STEADY;
        let points = common::open_loop_frf(&common::plan(&practice), &freqs);
        let measured_at: Vec<f64> = points.iter().map(|p| p.freq_hz).collect();
        let measured: Vec<Complex64> = points
            .iter()
            .map(|p| Complex64::from_polar(p.magnitude, p.phase_deg.to_radians()))
            .collect();
        let id = studies::identify::identify(&model, &measured_at, &measured).unwrap();
        let truth = PracticeDraw::draw(seed, &Default::default(), common::STEADY);
        let drawn = studies::identify::table_5_2(&truth.stage);
        let mount = id
            .extra_modes
            .iter()
            .map(|m| m.hz / truth.mount_hz - 1.0)
            .min_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(f64::INFINITY);
        assert!(
            mount.abs() < 0.05,
            "seed {seed}: the mount at {:.0} Hz found {:+.1} % off",
            truth.mount_hz,
            100.0 * mount
        );
        assert_eq!(
            id.uncertainty,
            studies::identify::UncertaintyBasis::Noise,
            "seed {seed}: {}",
            id.uncertainty_note()
        );
        let mut line = format!(
            "seed {seed}, mount {:.0} Hz found {:+.2} %, error in σ:",
            truth.mount_hz,
            100.0 * mount
        );
        for ((fitted, sigma), drawn) in id.fitted.iter().zip(&id.rel_std).zip(&drawn) {
            let z = (fitted / drawn - 1.0) / sigma;
            line += &format!(" {z:+.2}");
            within_1 += usize::from(z.abs() <= 1.0);
            within_2 += usize::from(z.abs() <= 2.0);
            values += 1;
        }
        println!("{line}");
    }
    let (one, two) = (
        within_1 as f64 / values as f64,
        within_2 as f64 / values as f64,
    );
    println!("within 1σ: {within_1} of {values} ({one:.3}); within 2σ: {within_2} ({two:.3})");
    assert!((0.60..=0.76).contains(&one), "1σ holds {one:.3}");
    assert!(two >= 0.90, "2σ holds {two:.3}");
}
