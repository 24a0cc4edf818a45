//! Processor in the loop: the same loop on two processors. The runtime's tick on the Cortex-M7
//! firmware (under QEMU) and in this process, each closed against the same simulated stage,
//! give the same samples and commands bit for bit (the loop digest: every sample's gap and
//! accelerometer reading and every command, as f64) and the same recorded frames, tick for
//! tick — for the Chapter 7 PID, an H2 state-space controller from `servo synth`, and a trip.
//!
//! These need the firmware and `qemu-system-arm`; CI builds the one, installs the other and
//! runs them:
//!   (cd firmware && cargo build --release)
//!   FTS_FIRMWARE=firmware/target/thumbv7em-none-eabihf/release/fts-firmware \
//!     cargo test --release -p studies --test pil -- --ignored

use recorder::Frame;
use run_config::{Loaded, Scenario};
use runner::pil::{PilError, PilOptions};
use runner::run::{run_on_target, run_with, RunOptions};
use runner::stop::StopRequest;
use runner::summary::Summary;
use runner::{Plan, RunError};
use studies::synth::{synthesize, SynthRequest, SynthWeights};

fn firmware() -> PilOptions {
    let path = std::env::var_os("FTS_FIRMWARE")
        .expect("FTS_FIRMWARE names the firmware ELF (see this file's header)");
    PilOptions::new(path)
}

fn options<'a>(stop: &'a StopRequest, progress: &'a mut dyn FnMut(u64, u64)) -> RunOptions<'a> {
    RunOptions {
        out: None,
        stop,
        progress,
        digest: true,
    }
}

fn on_host(plan: &Plan) -> (Summary, Vec<Frame>) {
    let stop = StopRequest::new();
    let mut frames = Vec::new();
    let s = run_with(plan, options(&stop, &mut |_, _| {}), |f| frames.push(*f)).unwrap();
    (s, frames)
}

fn on_target(plan: &Plan, pil: &PilOptions) -> Result<(Summary, Vec<Frame>), RunError> {
    let stop = StopRequest::new();
    let mut frames = Vec::new();
    let s = run_on_target(plan, options(&stop, &mut |_, _| {}), pil, |f| {
        frames.push(*f)
    })?;
    Ok((s, frames))
}

/// The two runs agree tick for tick; returns the target's summary.
fn assert_same_loop(plan: &Plan, least_ticks: usize) -> Summary {
    let (host, host_frames) = on_host(plan);
    let (target, target_frames) = on_target(plan, &firmware()).unwrap();
    assert!(
        host_frames.len() >= least_ticks,
        "{} ticks",
        host_frames.len()
    );
    assert_eq!(host_frames.len(), target_frames.len());
    for (k, (h, t)) in host_frames.iter().zip(&target_frames).enumerate() {
        assert_eq!(h, t, "tick {k}: the target's frame differs from the host's");
    }
    assert_eq!(host.meta.loop_digest, target.meta.loop_digest);
    assert_eq!(host.trip, target.trip);
    assert_eq!(host.meta.end_reason, target.meta.end_reason);
    let t = target
        .meta
        .target
        .clone()
        .expect("a PIL run says where it ran");
    assert!(t.lost.is_none(), "{:?}", t.lost);
    assert!(t.instructions_per_tick_mean > 0.0);
    assert!(t.stack_used_bytes > 0);
    target
}

fn loaded(duration_s: f64) -> Loaded {
    let mut l = Loaded::default();
    l.config.run.duration_s = duration_s;
    l
}

#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn the_chapter7_pid_loop_is_the_same_on_the_target() {
    // 2 016 ticks at 199.6 kHz, noise and base vibration on (the default run).
    let plan = Plan::new(&loaded(0.0101)).unwrap();
    let summary = assert_same_loop(&plan, 2000);
    let t = summary.meta.target.unwrap();
    assert!(t.build.contains("f64 in hardware"), "{}", t.build);
}

/// A fifth of a second of a 1 kHz sine at 199.6 kHz (39 920 ticks, the loop settled into its
/// steady state): tick for tick the host's, at about 80 µs of wall time a tick over the
/// semihosting link.
#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn a_fifth_of_a_second_of_a_sine_is_the_same_on_the_target() {
    let mut l = loaded(0.2);
    l.config.scenario = Scenario::Sine {
        amplitude_m: 1e-6,
        frequency_hz: 1000.0,
    };
    assert_same_loop(&Plan::new(&l).unwrap(), 39_900);
}

#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn an_h2_state_space_loop_is_the_same_on_the_target() {
    let mut l = loaded(0.1);
    l.config.plant.timing.servo_rate_hz = 20_000.0;
    let base = Plan::new(&l).unwrap();
    let request = SynthRequest {
        weights: SynthWeights::Exact {
            effort_weight: 1.0,
            sensor_noise_scale: 1.0,
        },
        order: Some(13),
    };
    let synth = synthesize(&base, &request).unwrap();
    assert_eq!(synth.prediction.states, 13);
    assert_same_loop(&synth.plan, 2000);
}

#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn a_trip_on_the_target_has_the_hosts_cause_and_tick() {
    // The 40 µm step: beyond the 20 µm following-error limit the tick it lands.
    let mut l = loaded(0.02);
    l.config.scenario = Scenario::Step {
        amplitude_m: 40e-6,
        at_s: 0.002,
    };
    let plan = Plan::new(&l).unwrap();
    let summary = assert_same_loop(&plan, 1000);
    let trip = summary.trip.expect("the step trips the loop");
    assert_eq!(trip.cause, "following-error");
    assert_eq!(summary.meta.end_reason.as_deref(), Some("tripped"));
}

#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn a_rate_the_part_cannot_hold_is_refused_before_the_run() {
    // The PID at 199.6 kHz takes about 700 instructions a tick: at 48 MHz that is ~15 µs,
    // three periods.
    let plan = Plan::new(&loaded(0.001)).unwrap();
    let mut pil = firmware();
    pil.model.clock_hz = 48e6;
    match on_target(&plan, &pil) {
        Err(RunError::Pil(PilError::Refused(why))) => {
            assert!(why.contains("holds at most"), "{why}");
            assert!(why.contains("plant.timing.servo_rate_hz"), "{why}");
        }
        other => panic!("expected a refusal, got {:?}", other.map(|r| r.0)),
    }
    // Forced, it runs and counts every tick over budget.
    pil.force = true;
    let (summary, _) = on_target(&plan, &pil).unwrap();
    let t = summary.meta.target.unwrap();
    assert_eq!(t.over_budget_ticks, summary.ticks);
}

#[test]
#[ignore = "needs the firmware and qemu-system-arm"]
fn a_deployment_edited_after_its_check_is_refused_by_the_target() {
    // The checked deployment opens; with one gain changed after the check the target's own
    // loop build refuses it, naming the digest that no longer matches.
    let plan = Plan::new(&loaded(0.001)).unwrap();
    let checked = runner::gain_range::checked(&plan).unwrap();
    let target = runner::pil::TargetLoop::start(&checked, &firmware()).unwrap();
    let _ = target.finish();
    let mut edited = checked;
    edited.controller.pid.kp *= 2.0;
    match runner::pil::TargetLoop::start(&edited, &firmware()) {
        Err(PilError::Refused(why)) => assert!(
            why.contains("controller.stability.sha256.controller")
                && why.contains("does not match"),
            "{why}"
        ),
        Err(e) => panic!("refused for another reason: {e}"),
        Ok(_) => panic!("the target took an edited deployment"),
    }
}
