//! The controller half of a tick on bad input: a non-finite reading latches the controller's
//! fault and trips machine protection; the command is the safe state from then on and both the
//! command and the telemetry say so.

use daq_io::{flags, Sensor};
use run_config::{Loaded, SafeState};
use runner::{Plan, PlanLoop};
use servo_runtime::TripCause;

fn sample(seq: u64, gap_v: f64) -> Sensor {
    Sensor {
        seq,
        time_s: seq as f64 * 5e-6,
        gap_v,
        ..Default::default()
    }
}

#[test]
fn a_nan_reading_gives_zero_volts_and_a_fault_flag() {
    let mut servo = PlanLoop::new(&Plan::new(&Loaded::default()).unwrap()).unwrap();
    let (c, t) = servo.tick(&sample(0, 0.01));
    let c = c.unwrap();
    assert!(c.dac_v != 0.0 && c.flags & flags::FAULT_CONTROLLER == 0);
    // The telemetry of tick 0 (before the bad reading) is clean.
    assert_eq!(t.unwrap().flags & flags::FAULT_CONTROLLER, 0);
    let (c, t) = servo.tick(&sample(1, f64::NAN));
    let c = c.unwrap();
    assert_eq!(c.dac_v, 0.0);
    assert_ne!(c.flags & flags::FAULT_CONTROLLER, 0);
    // The tick that read it says so.
    assert_ne!(t.unwrap().flags & flags::FAULT_CONTROLLER, 0);
    // Latched: good readings afterwards still give 0 V, and the command and the telemetry of
    // every tick from the bad one on carry the flag.
    for k in 2..10 {
        let (c, t) = servo.tick(&sample(k, 0.01));
        let c = c.unwrap();
        assert_eq!(c.dac_v, 0.0);
        assert_ne!(c.flags & flags::FAULT_CONTROLLER, 0);
        assert_ne!(t.unwrap().flags & flags::FAULT_CONTROLLER, 0);
    }
}

#[test]
fn a_nan_reading_trips_to_the_configured_safe_state() {
    for (state, held) in [(SafeState::Zero, false), (SafeState::Hold, true)] {
        let mut l = Loaded::default();
        l.config.protection.safe_state = state;
        let mut servo = PlanLoop::new(&Plan::new(&l).unwrap()).unwrap();
        let before = servo.tick(&sample(0, 0.01)).0.unwrap().dac_v;
        let (c, _) = servo.tick(&sample(1, f64::NAN));
        let c = c.unwrap();
        assert_eq!(servo.trip(), Some((TripCause::NotFinite, 1)));
        let bits = flags::TRIPPED | flags::TRIP_NOT_FINITE | flags::FAULT_CONTROLLER;
        assert_eq!(c.flags & bits, bits);
        let want = if held { before } else { 0.0 };
        assert_eq!(c.dac_v, want);
        // 5 ms = 998 ticks of safe state, then the run is over.
        for k in 2..=999 {
            let (c, t) = servo.tick(&sample(k, 0.01));
            assert_eq!(c.unwrap().dac_v, want);
            assert_eq!(t.unwrap().flags & bits, bits);
            assert_eq!(servo.run_over(), k == 999, "tick {k}");
        }
    }
}

/// The runtime's thesis prototype is what `servo deploy` makes of the default configuration:
/// the stage's numbers from the plant model, the Chapter 7 PID, and its loop's checked range
/// (bisection to 1e-6, eigenvalues to rounding).
#[test]
fn the_runtime_thesis_prototype_is_the_default_deployment() {
    let plan = Plan::new(&Loaded::default()).unwrap();
    let (deployed, _) = runner::deploy::deployment_file(&plan).unwrap();
    let preset = servo_config::Deployment::thesis_prototype();
    let (a, b) = (deployed.stability.unwrap(), preset.stability.unwrap());
    for (x, y) in [
        (a.spectral_radius, b.spectral_radius),
        (a.unstable_below, b.unstable_below),
        (a.unstable_above, b.unstable_above),
    ] {
        assert!((x - y).abs() <= 1e-9 * y, "{x} vs {y}");
    }
    assert_eq!(
        servo_config::Deployment {
            stability: None,
            ..deployed
        },
        servo_config::Deployment {
            stability: None,
            ..preset
        }
    );
}
