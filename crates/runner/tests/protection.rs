//! Machine protection in whole closed-loop runs of the simulated prototype: each limit trips
//! at the first tick its condition shows in the recorded frames (found independently here,
//! from the frames: the following error and the reading of a frame are what its tick acted
//! on, so that tick trips; a saturated command is seen by the next), the loop then commands
//! the configured safe state, the run ends `after_trip_s` later as `tripped`, and the summary
//! names cause and tick.

use daq_io::flags;
use recorder::Frame;
use run_config::{Loaded, ProtectionConfig, SafeState, Scenario};
use runner::run::run_to_end_with;
use runner::summary::Summary;
use runner::Plan;

/// Ticks of the default 5 ms safe-state interval at 199.6 kHz.
const AFTER_TICKS: u64 = 998;

/// A step of `amplitude_m` at 2 ms in a 20 ms run, with protection as `edit` makes it.
fn step_run(amplitude_m: f64, edit: impl FnOnce(&mut ProtectionConfig)) -> (Summary, Vec<Frame>) {
    let mut l = Loaded::default();
    l.config.run.duration_s = 0.02;
    l.config.scenario = Scenario::Step {
        amplitude_m,
        at_s: 0.002,
    };
    edit(&mut l.config.protection);
    let plan = Plan::new(&l).unwrap();
    let mut frames = Vec::new();
    let summary = run_to_end_with(&plan, |f| frames.push(*f)).unwrap();
    (summary, frames)
}

fn bits(f: &Frame) -> u32 {
    f.telemetry.flags as u32
}

/// Checks what every trip shares: the first tripped frame is `tick`, with `cause`'s bit; every
/// frame from it on is tripped and commands `safe(k)`; none before it is; the run ends
/// `AFTER_TICKS` later; the summary and its end reason say so.
fn assert_tripped(
    (summary, frames): &(Summary, Vec<Frame>),
    cause: &str,
    tick: usize,
    safe: impl Fn(usize) -> f64,
) {
    let trip = summary.trip.as_ref().expect("the run tripped");
    assert_eq!((trip.cause.as_str(), trip.tick), (cause, tick as u64));
    assert!(frames[..tick].iter().all(|f| bits(f) & flags::TRIPPED == 0));
    for (k, f) in frames.iter().enumerate().skip(tick) {
        assert_ne!(bits(f) & flags::TRIPPED, 0, "tick {k}");
        let want = safe(k);
        assert!(
            (f.telemetry.control_v as f64 - want).abs() <= 1e-6 * want.abs().max(1e-3),
            "tick {k}: {} V, safe state {want} V",
            f.telemetry.control_v
        );
    }
    assert_eq!(frames.len() as u64, tick as u64 + AFTER_TICKS + 1);
    assert_eq!(summary.meta.end_reason.as_deref(), Some("tripped"));
}

#[test]
fn a_step_beyond_the_following_error_limit_trips_to_zero_volts() {
    let run = step_run(22e-6, |_| {});
    // The first tick whose following error (its reference with the reading it acted on) passed
    // 20 µm trips: its own command is already the safe state.
    let over = run
        .1
        .iter()
        .position(|f| f.telemetry.following_error_m.abs() > 20e-6)
        .unwrap();
    assert_tripped(&run, "following-error", over, |_| 0.0);
    assert_ne!(bits(&run.1[over]) & flags::TRIP_FOLLOWING_ERROR, 0);
    // Below the limit, the same step runs to its end untripped.
    let (ok, frames) = step_run(18e-6, |_| {});
    assert!(ok.trip.is_none() && frames.iter().all(|f| bits(f) & flags::TRIPPED == 0));
    assert_eq!(ok.meta.end_reason.as_deref(), Some("completed"));
}

#[test]
fn a_clipped_gap_reading_trips_and_the_tool_stays_in_reach() {
    // 40 µm: beyond the sensor's ±25.6 µm (the run that travelled 2.7 mm).
    let run = step_run(40e-6, |p| {
        p.following_error_m = 0.0;
        p.saturation_s = 0.0;
    });
    let clipped = run
        .1
        .iter()
        .position(|f| bits(f) & flags::GAP_CLIPPED != 0)
        .unwrap();
    assert_tripped(&run, "sensor-range", clipped, |_| 0.0);
    // Unprotected, the blind loop drives the tool millimetres (the 2.7 mm); tripped,
    // it coasts from where the clip caught it (≈ 0.14 mm) and springs back.
    let worst = |frames: &[Frame]| {
        frames
            .iter()
            .map(|f| f.truth.tool_m.abs())
            .fold(0.0, f32::max)
    };
    let (_, unprotected) = step_run(40e-6, |p| p.enabled = false);
    let (tripped, blind) = (worst(&run.1), worst(&unprotected));
    assert!(
        blind > 1e-3 && tripped < 0.1 * blind,
        "{tripped} m tripped, {blind} m blind"
    );
}

#[test]
fn a_position_limit_trips_inside_the_sensor_range_and_holds_the_command() {
    let run = step_run(1e-6, |p| {
        p.position_limit_m = Some(0.5e-6);
        p.safe_state = SafeState::Hold;
    });
    let over = run
        .1
        .iter()
        .position(|f| f.telemetry.measured_m.abs() > 0.5e-6)
        .unwrap();
    // The tick that read it trips and holds the last normal command, the tick before's.
    let held = run.1[over - 1].telemetry.control_v as f64;
    assert!(held.abs() > 1e-3 && held.abs() < 10.0, "{held} V");
    assert_tripped(&run, "sensor-range", over, |_| held);
}

#[test]
fn saturation_longer_than_the_limit_trips_and_retracts() {
    // 15 µm: the step drives the command to its 10 V limit for longer than 10 ticks (50 µs).
    let limit_ticks = 10;
    let run = step_run(15e-6, |p| {
        p.saturation_s = limit_ticks as f64 / 199_600.0;
        p.safe_state = SafeState::Retract;
    });
    let saturated: Vec<bool> = run
        .1
        .iter()
        .map(|f| bits(f) & flags::SATURATED != 0)
        .collect();
    // The first tick that ends a run of more than `limit_ticks` saturated ticks.
    let mut streak = 0;
    let over = saturated
        .iter()
        .position(|&s| {
            streak = if s { streak + 1 } else { 0 };
            streak > limit_ticks
        })
        .unwrap();
    let gain = plant_sim::PlantParams::default().dc_gain_m_per_v();
    let (target, step) = (-5e-6 / gain, 5e-3 / gain / 199_600.0);
    let start = run.1[over].telemetry.control_v as f64;
    let trip = over + 1;
    // A ramp from the last command at 5 mm/s (through the static gain) to −5 µm, then held.
    assert_tripped(&run, "saturation", trip, |k| {
        let ramp = start - step * (k - trip + 1) as f64;
        ramp.max(target)
    });
}

#[test]
fn without_protection_nothing_trips() {
    let (summary, frames) = step_run(40e-6, |p| p.enabled = false);
    assert!(summary.trip.is_none());
    assert!(frames.iter().all(|f| bits(f) & flags::TRIPPED == 0));
    assert_eq!(frames.len(), 3992);
}
