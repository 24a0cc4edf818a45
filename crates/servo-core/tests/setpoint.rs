//! The generators on the plant's time: a seek lands where ticking would, and a chirp's
//! instantaneous frequency is the sweep's.

use servo_core::{Block, ChirpConfig, SineConfig, Sweep};
use std::f64::consts::PI;

/// A seek lands on the value ticking would give there, forward and back: the sine of the
/// tick's time, not of the updates made.
#[test]
fn a_seek_lands_where_ticking_would() {
    let sine = SineConfig {
        amplitude: 1.0,
        frequency_hz: 200.0,
        phase_rad: 0.3,
        offset: 0.0,
    };
    let (mut ticked, mut sought) = (sine.try_build(1e-5).unwrap(), sine.try_build(1e-5).unwrap());
    for _ in 0..1234 {
        ticked.update(());
    }
    sought.seek(1234);
    let t = 1234.0 * 1e-5;
    let (a, b) = (sought.update(()).position, ticked.update(()).position);
    assert_eq!(a, b);
    assert!((a - libm::sin(2.0 * PI * 200.0 * t + 0.3)).abs() < 1e-12);
    sought.seek(17);
    let back = libm::sin(2.0 * PI * 200.0 * 17e-5 + 0.3);
    assert!((sought.update(()).position - back).abs() < 1e-12);
}

#[test]
fn chirp_instantaneous_frequency() {
    let c = ChirpConfig {
        amplitude: 1.0,
        f_start_hz: 10.0,
        f_end_hz: 1000.0,
        duration_s: 2.0,
        sweep: Sweep::Exponential,
    }
    .try_build(1e-5)
    .unwrap();
    assert!((c.frequency_hz(1.0) - 100.0).abs() < 1e-9);
    assert!((c.frequency_hz(2.0) - 1000.0).abs() < 1e-9);
}
