//! The survivable stall, checked against simulation: a stall of the predicted length, injected
//! into a lockstep run on an injected clock (the DAC held, the plant's own watchdog judging
//! the silence, the controller taking the newest sample after it), is ridden out from every
//! phase of the reference; one half as long again is not. And a host that stalls longer than
//! a loop survives is refused, naming both.

use run_config::{Loaded, RunConfig, Scenario};
use runner::stall::{check_host, simulate, survivable, HostStalls, Limit, MAX_STALL_S};
use runner::{Plan, RunError};

/// The thesis prototype and PID at 199.6 kHz, noise on, `scenario` for `duration_s`.
fn plan(scenario: Scenario, duration_s: f64) -> Plan {
    let mut c = RunConfig {
        scenario,
        ..Default::default()
    };
    c.run.duration_s = duration_s;
    Plan::new(&Loaded {
        config: c,
        ..Default::default()
    })
    .unwrap()
}

/// Stalls starting at 36 phases of one period of the reference, after the loop settled
/// (0.1 s, past the watchdog's 50 ms grace window): how many the loop rode out.
fn ridden_out(
    p: &Plan,
    period_ticks: u64,
    stall_ticks: u64,
    timeout_s: f64,
) -> (usize, Vec<String>) {
    let mut causes = Vec::new();
    let mut survived = 0;
    for i in 0..36 {
        let start = 20_000 + period_ticks * i / 36;
        let run = simulate(p, start, stall_ticks, timeout_s).unwrap();
        if run.survived() {
            survived += 1;
        } else {
            causes.push(format!(
                "start {start}: {:?} {:?}",
                run.trip, run.peer_lost_at
            ));
        }
    }
    (survived, causes)
}

/// Sines whose stall is limited by the stage, not the watchdog (a 50 ms peer timeout): 12 µm
/// at 50 Hz, where the reference runs away from the held stage until the following error
/// reaches its 20 µm limit, and 9 µm at 300 Hz, where the recovery saturates the command and
/// overshoots toward the sensor's range.
#[test]
fn a_sine_rides_out_its_predicted_stall_from_every_phase_and_not_one_half_as_long_again() {
    let timeout_s = 0.05;
    for (amplitude_m, frequency_hz) in [(12e-6, 50.0), (9e-6, 300.0)] {
        let scenario = Scenario::Sine {
            amplitude_m,
            frequency_hz,
        };
        let p = plan(scenario, 0.15);
        let s = survivable(&p, timeout_s).unwrap();
        let m = s.physics_ticks.expect("the stage limits this stall");
        assert!(m < s.watchdog_ticks, "{s:?}");
        assert!(
            matches!(s.limit(), Limit::FollowingError | Limit::SensorRange),
            "{s:?}"
        );
        // Independently, at 50 Hz (far below the loop's bandwidth, the stage follows closely):
        // a stall from the trough with the stage staying there lets the following error grow
        // as A·(1 − cos ωt), reaching the 20 µm limit at ωt = acos(1 − 20 µm / A).
        let period = p.period_s();
        if frequency_hz < 100.0 {
            let w = std::f64::consts::TAU * frequency_hz;
            let from_trough = libm::acos(1.0 - 20e-6 / amplitude_m) / w;
            let predicted = m as f64 * period;
            assert!(
                (predicted / from_trough - 1.0).abs() < 0.15,
                "predicted {predicted} s, from the trough {from_trough} s"
            );
        }
        let period_ticks = (1.0 / (frequency_hz * period)).round() as u64;
        let (ok, causes) = ridden_out(&p, period_ticks, m, timeout_s);
        assert_eq!(
            ok, 36,
            "{amplitude_m} m at {frequency_hz} Hz, {m} ticks: {causes:?}"
        );
        let longer = m * 3 / 2;
        let (ok, causes) = ridden_out(&p, period_ticks, longer, timeout_s);
        assert!(
            ok < 36,
            "{amplitude_m} m at {frequency_hz} Hz: a stall of {longer} ticks was ridden out from every phase"
        );
        assert!(
            causes
                .iter()
                .all(|c| c.contains("FollowingError") || c.contains("SensorRange")),
            "{causes:?}"
        );
    }
}

/// Holding position, the held DAC keeps the stage where it was: the stage alone rides out
/// more than the 100 ms searched, so the run's peer timeout (0.5 ms by default) is what
/// limits it — a stall one tick shorter than it passes, half as long again ends the run at
/// 0 V (peer-lost), as the plant would.
#[test]
fn holding_position_the_watchdog_limits_the_stall_and_the_stage_outlasts_it() {
    let p = plan(Scenario::Hold, 0.15);
    let timeout_s = p.config.realtime.peer_timeout_s;
    let s = survivable(&p, timeout_s).unwrap();
    assert_eq!(s.physics_ticks, None, "{s:?}");
    assert_eq!(s.limit(), Limit::PeerTimeout);
    // Silence counts from the sample after the last command until the next deadline (the
    // plant's `serve` waits for a command until one period after the sample went out): m
    // ticks of it last (m + 1)·T, a loss at 0.5 ms: 99 ticks pass at 199.6 kHz, 100 do not.
    let expected = (timeout_s / p.period_s()).ceil() as u64 - 1;
    assert_eq!(s.ticks(), expected);
    assert_eq!(expected, 99);
    for start in [20_000, 20_123] {
        let run = simulate(&p, start, s.ticks(), timeout_s).unwrap();
        assert!(run.survived(), "{run:?}");
        let run = simulate(&p, start, s.ticks() * 3 / 2, timeout_s).unwrap();
        assert_eq!(run.peer_lost_at, Some(start + s.ticks()), "{run:?}");
        assert_eq!(run.trip, None);
    }
    // With the watchdog out of the way, a stall close to the 100 ms searched leaves the stage
    // within 2 µm of where it was held.
    let long = plan(Scenario::Hold, 0.25);
    let stall = (0.9 * MAX_STALL_S / long.period_s()) as u64;
    let run = simulate(&long, 20_000, stall, 1.0).unwrap();
    assert!(run.survived(), "{run:?}");
    assert!(run.peak_measured_m < 2e-6, "{run:?}");
}

/// A run refused up front on an injected qualification: the message names the host's stall
/// and the loop's, and what to change; a host that stalls less than half of it passes.
#[test]
fn a_host_that_stalls_longer_than_the_loop_survives_is_refused_naming_both() {
    let p = plan(Scenario::Hold, 0.15);
    let s = survivable(&p, p.config.realtime.peer_timeout_s).unwrap();
    let host = |worst_s: f64| HostStalls {
        worst_s,
        measured_s: 10.0,
        rate_hz: 199_600.0,
        source: "servo latency, 10 s at 199.6 kHz on test-host".into(),
    };
    let e = check_host(&s, &host(3.8e-3)).unwrap_err();
    assert!(matches!(e, RunError::HostTooSlow(_)));
    let text = e.to_string();
    for expected in [
        "this host stalled 3800.0 µs",
        "servo latency, 10 s at 199.6 kHz on test-host",
        "survives stalls up to 496.0 µs",
        "realtime.peer_timeout_s",
    ] {
        assert!(text.contains(expected), "{expected:?} in {text}");
    }
    check_host(&s, &host(0.2e-3)).unwrap();
    // Twice the host's worst is the margin: 0.25 ms of 0.496 ms is refused.
    assert!(check_host(&s, &host(0.25e-3)).is_err());
}
