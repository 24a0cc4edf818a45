//! A loop that fell behind takes the newest sample and skips the rest (real time): its
//! built-in trajectory stays on the plant's time — the reference of a sample is the trajectory
//! at that sample's tick, however many ticks were skipped before it.

use servo_config::{Deployment, ReferenceSpec};
use servo_runtime::Servo;
use std::f64::consts::TAU;

/// Without preview and with a smoothing window that reads the trajectory 50 ticks ahead: skips
/// of 417 ticks (2 ms: a descheduled controller), of one tick and of three (shorter than the
/// preview, so the window is primed again over ticks it had already read).
#[test]
fn the_reference_of_a_sample_after_a_skip_is_the_trajectory_at_its_tick() {
    let (amplitude, f) = (2e-6, 350.0);
    for smoothing_hz in [0.0, 2000.0] {
        let d = Deployment {
            reference: ReferenceSpec::Sine {
                amplitude_m: amplitude,
                frequency_hz: f,
            },
            smoothing_hz,
            ..Deployment::thesis_prototype()
        };
        let period = d.period_s();
        let mut servo = Servo::new(&d).unwrap();
        let mut sample = daq_io::Sensor::default();
        let ticks = (0..100).chain(517..600).chain(601..640).chain(644..700);
        for k in ticks {
            sample.seq = k;
            servo.tick(&sample);
            let r = servo.telemetry().unwrap().reference_m;
            let expected = amplitude * libm::sin(TAU * f * k as f64 * period);
            assert!(
                (r - expected).abs() < 1e-12 * amplitude,
                "smoothing {smoothing_hz} Hz, tick {k}: reference {r} m, the sine at the tick {expected} m"
            );
        }
    }
}
