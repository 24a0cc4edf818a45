//! The documented calibration (README "Calibration"): the 468 Hz-bandwidth PID on the 0.174 kg
//! stage with all default disturbances gives a following error near the thesis's 0.83 nm RMS
//! (§5.7.4, Fig 5-16) and a true tool error near its 0.23 nm RMS.

use plant_sim::cutting::CuttingProfile;
use plant_sim::{PlantParams, Simulator};
use servo_core::{Block, PidConfig};

/// The Ch7 gains scaled by 0.3906 for a 468 Hz closed-loop bandwidth on the heavy stage
/// (`cargo run --release -p studies --example calibrate` prints how they were found).
const PID_468_HZ: PidConfig = PidConfig {
    kp: 0.6445,
    ki: 219.52,
    kd: 3.7107e-4,
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
    // Statistical scatter of a 2.5 s run is ≈ 3 %; the calibration meets 0.83 / 0.23 nm
    // exactly in the budget (the example prints it).
    assert!((f - 0.83).abs() < 0.05, "following error {f:.3} nm");
    assert!((t - 0.23).abs() < 0.03, "true error {t:.3} nm");
}
