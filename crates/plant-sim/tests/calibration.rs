//! The documented calibration (README "Calibration"): the 468 Hz-bandwidth PID on the 0.175 kg
//! stage with all default disturbances gives a following error near the thesis's 0.83 nm RMS
//! (§5.7.4, Fig 5-16); the true tool error is reported beside it.

use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};
use servo_core::{Block, PidConfig};

/// The Ch7 gains scaled by 0.3905 for a 468 Hz closed-loop bandwidth on the heavy stage
/// (`cargo run --release -p plant-sim --example calibrate` prints how they were found).
const PID_468_HZ: PidConfig = PidConfig {
    kp: 0.6443,
    ki: 219.46,
    kd: 3.7097e-4,
    ..PidConfig::THESIS_CH7
};

fn rms(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

#[test]
fn following_error_near_thesis_at_468_hz() {
    let mut p = PlantParams::heavy();
    p.noise.accel = false; // no accelerometer in the Chapter 5 loop
    let mut sim = Simulator::new(&p, 5, &CuttingProfile::None).unwrap();
    let mut pid = PID_468_HZ.try_build(p.period_s()).unwrap();
    let n = (3.0 * p.timing.servo_rate_hz) as usize;
    let (mut follow, mut truth) = (Vec::new(), Vec::new());
    let mut u = 0.0;
    for k in 0..n {
        let (s, t) = sim.step(u);
        u = pid.update(-s.gap_v);
        if k > n / 6 {
            follow.push(s.gap_v / p.capa.sensitivity_v_per_m);
            truth.push(t.tool_m);
        }
    }
    let (f, t) = (rms(&follow) * 1e9, rms(&truth) * 1e9);
    println!("following {f:.3} nm RMS, true {t:.3} nm RMS");
    // Statistical scatter of a 2.5 s run is ≈ 3 %; the calibration targets 0.83 nm.
    assert!((f / 0.83 - 1.0).abs() < 0.10, "following error {f:.3} nm");
    // The model's true error: sensor noise mostly stays out of it (|T| small above 468 Hz),
    // current noise moves the tool as much as the sensor sees (≈ 0.6 nm; thesis 0.23 nm).
    assert!(
        t < f,
        "true error {t:.3} nm must be below the following error"
    );
    assert!((0.45..0.75).contains(&t), "true error {t:.3} nm");
}
