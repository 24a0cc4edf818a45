//! A loop that fell behind takes the newest sample and skips the rest (real time): its
//! built-in trajectory stays on the plant's time — the reference of a sample is the trajectory
//! at that sample's tick, however many ticks were skipped before it.

use servo_runtime::{Deployment, ReferenceSpec, Servo};
use std::f64::consts::TAU;

#[test]
fn the_reference_of_a_sample_after_a_skip_is_the_trajectory_at_its_tick() {
    let (amplitude, f) = (2e-6, 350.0);
    let d = Deployment {
        reference: ReferenceSpec::Sine {
            amplitude_m: amplitude,
            frequency_hz: f,
        },
        ..Deployment::thesis_prototype()
    };
    let period = d.period_s();
    let mut servo = Servo::new(&d).unwrap();
    let mut sample = daq_io::Sensor::default();
    // Ticks 0..100, then the samples of 100..517 skipped (2 ms: a descheduled controller),
    // then on from 517, and another skip of one tick.
    let ticks = (0..100).chain(517..600).chain(601..640);
    for k in ticks {
        sample.seq = k;
        servo.tick(&sample);
        let r = servo.telemetry().unwrap().reference_m;
        let expected = amplitude * libm::sin(TAU * f * k as f64 * period);
        assert!(
            (r - expected).abs() < 1e-12 * amplitude.max(1.0),
            "tick {k}: reference {r} m, the sine at the tick {expected} m"
        );
    }
}
