//! Embedding the controller in a DAQ daemon (the design card's third use): the daemon's own
//! loop reads the ADC, runs the servo loop (servo-core's controller with the reference, the
//! feedforward and machine protection, as `servo run` builds it) and writes the DAC — no IPC on
//! the servo path. Off the servo path it publishes telemetry (and truth, when the hardware
//! knows it) and health, and takes the control plane over iceoryx2 exactly as `servo
//! controller` does: gain changes checked against the loop's stability margin and
//! acknowledged, STOP at a tick boundary. So `servo record`, `servo ctl` and the Python tap
//! work against it unchanged.
//!
//! The "hardware" here is the simulated stage (`SimBackend`), so the example runs anywhere;
//! a lab replaces it with its ADC/DAC driver (any `daq_io::Backend`).
//!
//! Options: `--prefix P`, `--seconds S` (default 1), `--config FILE` (a `servo` config: rate,
//! controller, `[realtime]` CPU / policy / wait for this loop; `servo record` off the CPU),
//! `--wait-recorder` (the first tick waits for `servo record`), `--demo`.
//!
//! ```text
//! cargo run --release -p runner --example embedded_daq -- --prefix lab --seconds 10 --wait-recorder
//! servo record --prefix lab --duration 10 --out lab.mcap     # in another terminal
//! servo ctl --prefix lab gain 0.8                            # acknowledged, recorded
//! cargo run --release -p runner --example embedded_daq -- --prefix lab --demo   # self-check
//! ```

use daq_io::clock::{monotonic_ns, Wait};
use daq_io::contract::command;
use daq_io::ipc::{leaf, take, BlockWriter, ControlSender, Endpoint, Tap};
use daq_io::{ack_status, flags, Backend, Control, Sensor, TelemetryBlock, TickStats, TruthBlock};
use runner::config::{Loaded, Role};
use runner::control_plane::{ControlPlane, Request, SERVICE_TICKS};
use runner::{Plan, ServoLoop, SimBackend};
use std::time::{Duration, Instant};

/// How long the demo's peer waits for the loop to listen, and for each acknowledgement.
const DEMO_TIMEOUT: Duration = Duration::from_secs(20);

/// How the daemon's run went.
struct Report {
    ticks: u64,
    overruns: u64,
    stats: TickStats,
    stop_cause: u32,
}

/// The daemon: `plan`'s loop on `hw`, paced to the wall clock, served on `prefix`; with
/// `wait_recorder`, the first tick waits (up to 30 s) for a recorder to subscribe.
fn daemon(
    plan: &Plan,
    prefix: &str,
    hw: &mut impl Backend,
    wait_recorder: bool,
) -> Result<Report, runner::RunError> {
    daq_io::realtime::apply(&plan.config.realtime.settings(Role::Plant))?;
    let ep = Endpoint::open(prefix, "plant")?;
    // This process is the run's controller too: `servo ctl gain` looks for one.
    let _controller_role = Endpoint::open(prefix, "controller")?;
    let mut servo = ServoLoop::new(plan)?;
    let mut plane = ControlPlane::new(&ep, plan, true)?;
    let telemetry_pub = ep.publisher::<TelemetryBlock>(leaf::TELEMETRY)?;
    let truth_pub = ep.publisher::<TruthBlock>(leaf::TRUTH)?;
    let run_id = daq_io::peers::random_id();
    let mut telemetry = BlockWriter::<TelemetryBlock>::new(run_id);
    let mut truth = BlockWriter::<TruthBlock>::new(run_id);
    if wait_recorder {
        let truth_service = ep.service::<TruthBlock>(leaf::TRUTH)?;
        let asked = std::time::Instant::now();
        while daq_io::ipc::subscriber_count(&truth_service) == 0
            && asked.elapsed() < Duration::from_secs(30)
        {
            std::thread::sleep(Duration::from_millis(5));
        }
    }
    daq_io::ipc::connect(&telemetry_pub);
    daq_io::ipc::connect(&truth_pub);
    plane.begin();

    let period_ns = (plan.period_s() * 1e9).round() as u64;
    let wait: Wait = plan.config.realtime.wait();
    let mut stats = TickStats::default();
    let (mut overruns, mut stop_cause) = (0, 0);
    let mut end_tick = plan.ticks();
    let mut sample = Sensor {
        run_id,
        ..hw.initial()
    };
    let base_ns = monotonic_ns() + period_ns;
    let mut k = 0;
    loop {
        // The servo path: wait for the tick, read, compute, write. Nothing else.
        let deadline = base_ns + k * period_ns;
        let started = wait.until(deadline);
        let late = started - deadline;
        if k >= end_tick {
            sample.flags |= flags::END;
        }
        let (cmd, t) = servo.tick(&sample);
        let Some(cmd) = cmd else { break };
        let s = hw.step(cmd.dac_v);
        stats.execution.record(monotonic_ns() - started);
        stats.lateness.record(late);
        // Off the servo path: the records of the tick, and every 2048 ticks the control plane.
        let overrun = late >= period_ns;
        overruns += overrun as u64;
        let tick_flags = if overrun { flags::OVERRUN } else { 0 };
        if let Some(t) = t {
            telemetry.push(&telemetry_pub, t);
        }
        if let Some(mut r) = hw.truth() {
            r.seq = k;
            r.flags |= tick_flags;
            truth.push(&truth_pub, r);
        }
        sample = Sensor {
            seq: k + 1,
            run_id,
            flags: s.flags | tick_flags,
            ..s
        };
        k += 1;
        if k.is_multiple_of(SERVICE_TICKS) {
            if let Request::Stop(cause) = plane.service(&mut servo, k, overruns, &stats) {
                end_tick = end_tick.min(k);
                stop_cause = cause;
            }
        }
    }
    telemetry.flush(&telemetry_pub, flags::END);
    truth.flush(&truth_pub, flags::END);
    plane.finish(k, overruns, &stats, 0, stop_cause);
    let service = ep.service::<TruthBlock>(leaf::TRUTH)?;
    daq_io::ipc::linger(&service, Duration::from_secs(5));
    Ok(Report {
        ticks: k,
        overruns,
        stats,
        stop_cause,
    })
}

/// `--demo`: what `servo ctl` and a telemetry tap do, from a thread: an unstable gain change
/// is refused, a stable one applied, then STOP; every telemetry block is of this run. It
/// sends once the loop listens on the control plane (a message sent before would be lost:
/// no history is kept), and gives up, naming what it waited for, after [`DEMO_TIMEOUT`].
fn demo_peer(prefix: &str) -> (Vec<u32>, u64) {
    let ep = Endpoint::open(prefix, &format!("ctl-{}", std::process::id())).expect("join");
    let tap = Tap::new(&ep).expect("tap");
    let sender = ControlSender::new(&ep).expect("control");
    assert!(
        ep.await_subscriber::<Control>(leaf::CONTROL, DEMO_TIMEOUT)
            .expect("control service"),
        "demo: the loop did not subscribe to the control plane within {DEMO_TIMEOUT:?}"
    );
    let mut statuses = Vec::new();
    let mut blocks = 0;
    for (id, (cmd, value)) in [
        (command::SET_GAIN_SCALE, 100.0),
        (command::SET_GAIN_SCALE, 0.8),
        (command::STOP, 0.0),
    ]
    .into_iter()
    .enumerate()
    {
        std::thread::sleep(Duration::from_millis(50));
        let id = id as u64 + 1;
        sender
            .send(Control {
                command: cmd,
                value,
                id,
                ..Default::default()
            })
            .expect("send");
        let sent = Instant::now();
        let status = loop {
            while take(&tap.telemetry).is_some() {
                blocks += 1;
            }
            if let Some(a) = take(&tap.ack).filter(|a| a.id == id) {
                break a.status;
            }
            assert!(
                sent.elapsed() < DEMO_TIMEOUT,
                "demo: no acknowledgement of control message {id} within {DEMO_TIMEOUT:?}"
            );
            std::thread::sleep(Duration::from_millis(1));
        };
        statuses.push(status);
    }
    (statuses, blocks)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let prefix = value("--prefix").unwrap_or_else(|| "lab".into());
    let demo = args.iter().any(|a| a == "--demo");
    let seconds: f64 = value("--seconds").map_or(if demo { 30.0 } else { 1.0 }, |s| {
        s.parse().expect("--seconds: a number of seconds")
    });
    let mut loaded = match value("--config") {
        Some(path) => Loaded::from_file(path.as_ref()).unwrap_or_else(|e| panic!("{e}")),
        None => Loaded::default(),
    };
    loaded.config.run.duration_s = seconds;
    let plan = Plan::new(&loaded).unwrap_or_else(|e| panic!("embedded daq: {e}"));
    let peer = demo.then(|| {
        let p = prefix.clone();
        std::thread::spawn(move || demo_peer(&p))
    });
    println!(
        "embedded daq: servo loop at {} Hz in this process, served on fts-servo/{prefix}/… ({} s)",
        plan.config.plant.timing.servo_rate_hz, seconds
    );
    let mut hw = SimBackend::for_run(&plan);
    let wait_recorder = args.iter().any(|a| a == "--wait-recorder");
    let r = daemon(&plan, &prefix, &mut hw, wait_recorder)
        .unwrap_or_else(|e| panic!("embedded daq: {e}"));
    let us = |ns: u64| ns as f64 * 1e-3;
    let (l, e) = (r.stats.lateness.summary(), r.stats.execution.summary());
    println!(
        "  {} ticks, {} overruns ({:.4} %), stop cause {}; lateness p50 {:.2} / p99.99 {:.2} / max {:.1} µs; execution p50 {:.2} / p99.99 {:.2} / max {:.1} µs",
        r.ticks,
        r.overruns,
        100.0 * r.overruns as f64 / r.ticks.max(1) as f64,
        r.stop_cause,
        us(l.p50_ns),
        us(l.p9999_ns),
        us(l.max_ns),
        us(e.p50_ns),
        us(e.p9999_ns),
        us(e.max_ns)
    );
    if let Some(p) = peer {
        let (statuses, blocks) = p.join().expect("demo peer");
        println!("  demo: acknowledgements {statuses:?}, {blocks} telemetry blocks tapped");
        assert_eq!(
            statuses,
            [
                ack_status::REFUSED_MARGIN,
                ack_status::APPLIED,
                ack_status::APPLIED
            ],
            "an unstable gain refused, a stable one applied, STOP applied"
        );
        assert!(r.ticks < plan.ticks(), "STOP ended the run early");
        assert!(blocks > 0, "telemetry was published");
    }
}
