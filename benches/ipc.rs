//! HIL transport bench (a dedicated binary: two processes, busy polling). Prints and writes
//! `target/ipc-bench.json`. All in the same run, driver on CPU 0 and peer on CPU 1:
//! - the hardware floor: two threads ping-ponging one cache line (an atomic counter);
//! - bare iceoryx2: the same service settings, raw API, a busy `receive` loop and pre-loaned
//!   samples as iceoryx2's own benchmark (the driver loans after the answer: a loan during the
//!   wait contends with the peer and costs ~0.5 µs here), no wrapper of ours;
//! - ours: the plant side as `daq_io::serve` sends and polls (`Sender`, `poll_held`) against
//!   the controller side as `servo controller` reads and writes (`ControllerLink`);
//! - a Unix stream socket ping-pong (blocking reads, the usual choice), same message sizes;
//!
//! each 10⁶ round trips (sockets 2·10⁵) after 10⁴ warm-up: min / median / p99 / p99.9 /
//! p99.99 / max; and the sustained lockstep tick rate of the full loop across processes
//! (simulated stage + Chapter 7 PID, `runner::hil`) against the in-process loop.
//!
//! Usage: `cargo bench --bench ipc` (the binary re-executes itself as the peer process).

use daq_io::clock::monotonic_ns;
use daq_io::ipc::{leaf, poll_held, ControllerLink, Endpoint, Sender};
use daq_io::realtime::{apply, RtSettings};
use daq_io::{Command, Daq, LatencyHistogram, Sensor};
use iceoryx2::prelude::*;
use run_config::Loaded;
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::{Child, Command as Process};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

const ROLE: &str = "FTS_IPC_BENCH_ROLE";
const EXCHANGES: u64 = 1_000_000;
const WARMUP: u64 = 10_000;
const SOCKET_EXCHANGES: u64 = 200_000;
const LOCKSTEP_S: f64 = 5.0;

fn pin(cpu: usize) {
    let cpu = cpu.min(daq_io::realtime::online_cpus() - 1);
    apply(&RtSettings {
        cpus: vec![cpu],
        ..Default::default()
    })
    .expect("pin to a CPU");
}

fn peer(role: &str, arg: &str) -> Child {
    unpin();
    Process::new(std::env::current_exe().unwrap())
        .env(ROLE, role)
        .arg(arg)
        .spawn()
        .expect("re-executing the bench as its peer")
}

fn arg() -> String {
    std::env::args().nth(1).expect("peer argument")
}

/// The hardware floor: a cache line bounced between two cores.
fn round_trip_cache_line() -> LatencyHistogram {
    let line = Arc::new(AtomicU64::new(0));
    let other = line.clone();
    let echo = std::thread::spawn(move || {
        pin(1);
        let mut k = 1;
        while k < 2 * (WARMUP + EXCHANGES) {
            while other.load(Ordering::Acquire) != k {
                std::hint::spin_loop();
            }
            other.store(k + 1, Ordering::Release);
            k += 2;
        }
    });
    pin(0);
    let mut h = LatencyHistogram::new();
    for i in 0..WARMUP + EXCHANGES {
        let t = monotonic_ns();
        line.store(2 * i + 1, Ordering::Release);
        while line.load(Ordering::Acquire) != 2 * i + 2 {
            std::hint::spin_loop();
        }
        if i >= WARMUP {
            h.record(monotonic_ns() - t);
        }
    }
    echo.join().unwrap();
    h
}

/// Bare iceoryx2 on the sensor/command services of `prefix`: (node, publisher, subscriber).
type Bare<P, S> = (
    Node<ipc::Service>,
    iceoryx2::port::publisher::Publisher<ipc::Service, P, ()>,
    iceoryx2::port::subscriber::Subscriber<ipc::Service, S, ()>,
);

/// A one-to-one service of the latest sample only, as the servo's are, opened or created.
fn service<T: std::fmt::Debug + ZeroCopySend + Copy + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
) -> iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()> {
    let name: ServiceName = name.try_into().unwrap();
    node.service_builder(&name)
        .publish_subscribe::<T>()
        .subscriber_max_buffer_size(1)
        .history_size(0)
        .enable_safe_overflow(true)
        .max_publishers(1)
        .max_subscribers(1)
        .max_nodes(2)
        .open_or_create()
        .unwrap()
}

fn bare<P, S>(prefix: &str, out: &str, back: &str) -> Bare<P, S>
where
    P: std::fmt::Debug + ZeroCopySend + Copy + 'static,
    S: std::fmt::Debug + ZeroCopySend + Copy + 'static,
{
    set_log_level(LogLevel::Error);
    let node = NodeBuilder::new().create::<ipc::Service>().unwrap();
    let name = |leaf: &str| format!("bench-bare/{prefix}/{leaf}");
    let publisher = service::<P>(&node, &name(out))
        .publisher_builder()
        .create()
        .unwrap();
    let subscriber = service::<S>(&node, &name(back))
        .subscriber_builder()
        .create()
        .unwrap();
    (node, publisher, subscriber)
}

/// Peer of the bare ping-pong: answers every sample, raw iceoryx2.
fn echo_bare(prefix: &str) {
    pin(1);
    let (_node, publisher, subscriber) = bare::<Command, Sensor>(prefix, "command", "sensor");
    let mut next = publisher.loan_uninit().unwrap();
    loop {
        let s = loop {
            if let Some(s) = subscriber.receive().unwrap() {
                break s;
            }
        };
        let (seq, end) = (s.seq, s.flags & daq_io::flags::END != 0);
        next.write_payload(Command {
            seq,
            ..Default::default()
        })
        .send()
        .unwrap();
        drop(s);
        if end {
            return;
        }
        next = publisher.loan_uninit().unwrap();
    }
}

fn round_trip_bare() -> LatencyHistogram {
    let prefix = format!("{}", std::process::id());
    let (_node, publisher, subscriber) = bare::<Sensor, Command>(&prefix, "sensor", "command");
    let mut child = peer("bare", &prefix);
    pin(0);
    let mut h = LatencyHistogram::new();
    let mut next = publisher.loan_uninit().unwrap();
    let total = WARMUP + EXCHANGES;
    let mut k = 0;
    // Tick 0 is sent again every 10 ms until the echo is subscribed and answers.
    while k <= total {
        let end = k == total;
        let t = monotonic_ns();
        next.write_payload(Sensor {
            seq: k,
            flags: if end { daq_io::flags::END } else { 0 },
            ..Default::default()
        })
        .send()
        .unwrap();
        let deadline = t + if k == 0 { 10_000_000 } else { 5_000_000_000 };
        let got = loop {
            if let Some(c) = subscriber.receive().unwrap() {
                if c.seq == k {
                    break true;
                }
            } else if k == 0 && monotonic_ns() > deadline {
                break false;
            }
        };
        let done = monotonic_ns();
        // Loaned after the answer: a loan while the peer works contends for its cache lines.
        next = publisher.loan_uninit().unwrap();
        if !got {
            continue; // the echo was not subscribed yet: send tick 0 again
        }
        if k >= WARMUP && !end {
            h.record(done - t);
        }
        k += 1;
    }
    child.wait().unwrap();
    h
}

/// Peer of our exchange: the controller side, as `servo controller` reads and writes.
fn echo_ours(prefix: &str) {
    pin(1);
    let ep = Endpoint::open(prefix, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_secs(30), Duration::from_secs(5)).unwrap();
    loop {
        let s = link.read().unwrap();
        if s.flags & daq_io::flags::END != 0 {
            return;
        }
        link.write(Command {
            seq: s.seq,
            dac_v: s.gap_v,
            ..Default::default()
        })
        .unwrap();
        link.prepare();
    }
}

/// Our exchange, plant side as `daq_io::serve` does it.
fn round_trip_ours() -> LatencyHistogram {
    let prefix = format!("bench-rt-{}", std::process::id());
    let ep = Endpoint::open(&prefix, "plant").unwrap();
    let mut sensor = Sender::new(ep.publisher::<Sensor>(leaf::SENSOR).unwrap());
    let command = ep.subscriber::<Command>(leaf::COMMAND).unwrap();
    let service = ep.service::<Sensor>(leaf::SENSOR).unwrap();
    let mut child = peer("ours", &prefix);
    pin(0);
    while daq_io::ipc::subscriber_count(&service) == 0 {
        std::thread::sleep(Duration::from_millis(1));
    }
    sensor.connect();
    let mut h = LatencyHistogram::new();
    for k in 0..WARMUP + EXCHANGES {
        let t = monotonic_ns();
        sensor.send(Sensor {
            seq: k,
            gap_v: k as f64,
            published_ns: t,
            ..Default::default()
        });
        let c = poll_held(&command, t + 5_000_000_000, |c| c.seq == k).expect("echo");
        let done = monotonic_ns();
        drop(c);
        if k >= WARMUP {
            h.record(done - t);
        }
        sensor.prepare();
    }
    sensor.send(Sensor {
        seq: WARMUP + EXCHANGES,
        flags: daq_io::flags::END,
        ..Default::default()
    });
    child.wait().unwrap();
    h
}

const MSG: usize = std::mem::size_of::<Sensor>();

fn echo_socket(path: &str) {
    pin(1);
    let mut s = UnixStream::connect(path).unwrap();
    let mut buf = [0u8; MSG];
    while s.read_exact(&mut buf).is_ok() {
        s.write_all(&buf[..std::mem::size_of::<Command>()]).unwrap();
    }
}

fn round_trip_socket() -> LatencyHistogram {
    // In a private folder of its own: no predictable path in the shared temp folder.
    let scratch = tempfile::tempdir().unwrap();
    let path = scratch.path().join("echo.sock");
    let listener = UnixListener::bind(&path).unwrap();
    let mut child = peer("socket", path.to_str().unwrap());
    let (mut s, _) = listener.accept().unwrap();
    pin(0);
    let (out, mut back) = ([7u8; MSG], [0u8; std::mem::size_of::<Command>()]);
    let mut h = LatencyHistogram::new();
    for k in 0..WARMUP + SOCKET_EXCHANGES {
        let t = monotonic_ns();
        s.write_all(&out).unwrap();
        s.read_exact(&mut back).unwrap();
        if k >= WARMUP {
            h.record(monotonic_ns() - t);
        }
    }
    drop(s);
    child.wait().unwrap();
    h
}

/// Lets this process run on every CPU again (its peers inherit its affinity).
fn unpin() {
    apply(&RtSettings {
        cpus: (0..daq_io::realtime::online_cpus()).collect(),
        ..Default::default()
    })
    .expect("unpin");
}

fn bench_plan() -> runner::Plan {
    let mut cfg = Loaded::default();
    cfg.config.run.duration_s = LOCKSTEP_S;
    runner::Plan::new(&cfg).unwrap()
}

/// (ticks, wall seconds) of the full loop across processes, and of the in-process loop.
fn lockstep_rate() -> ((u64, f64), (u64, f64)) {
    let plan = bench_plan();
    let prefix = format!("bench-ls-{}", std::process::id());
    let mut child = peer("controller", &prefix);
    let stop = runner::stop::StopRequest::new();
    let options = runner::hil::PlantOptions {
        pacing: daq_io::serve::Pacing::Lockstep,
        wait_for_recorder: false,
        wait_for_start: false,
        peer_timeout: None,
    };
    let r = runner::hil::plant(&plan, &prefix, &options, &stop).unwrap();
    child.wait().unwrap();
    let start = monotonic_ns();
    let s = runner::run::run_to_end(&plan).unwrap();
    (
        (r.ticks, r.wall_s),
        (s.ticks, (monotonic_ns() - start) as f64 * 1e-9),
    )
}

fn row(name: &str, h: &LatencyHistogram) -> serde_json::Value {
    let l = h.summary();
    let us = |ns: u64| ns as f64 * 1e-3;
    println!(
        "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
        l.count,
        us(l.min_ns),
        us(l.p50_ns),
        us(l.p99_ns),
        us(l.p999_ns),
        us(l.p9999_ns),
        us(l.max_ns)
    );
    serde_json::to_value(l).unwrap()
}

fn main() {
    match std::env::var(ROLE).as_deref() {
        Ok("bare") => return echo_bare(&arg()),
        Ok("ours") => return echo_ours(&arg()),
        Ok("socket") => return echo_socket(&arg()),
        Ok("controller") => {
            let stop = runner::stop::StopRequest::new();
            runner::hil::controller(&bench_plan(), &arg(), &stop).unwrap();
            return;
        }
        _ => {}
    }
    if std::env::args().any(|a| a == "--list") {
        return; // `cargo test --benches` probes with --list
    }
    println!("Round trip, driver on CPU 0 and peer on CPU 1, µs:\n");
    println!("| exchange | round trips | min | median | p99 | p99.9 | p99.99 | max |");
    println!("|---|---|---|---|---|---|---|---|");
    let floor = row(
        "cache-line ping-pong, two threads (hardware floor)",
        &round_trip_cache_line(),
    );
    let bare = row(
        "bare iceoryx2 0.10, two processes (raw API, pre-loaned samples)",
        &round_trip_bare(),
    );
    let ours = row(
        "ours: plant (serve) ↔ controller (ControllerLink), two processes",
        &round_trip_ours(),
    );
    let sock = row(
        "Unix stream socket, blocking reads, two processes (baseline)",
        &round_trip_socket(),
    );
    let ratio = ours["p50_ns"].as_f64().unwrap() / bare["p50_ns"].as_f64().unwrap();
    println!("\nours / bare iceoryx2 median: {ratio:.2}×");
    let ((ticks, wall), (in_ticks, in_wall)) = lockstep_rate();
    let (hil_khz, in_khz) = (ticks as f64 / wall / 1e3, in_ticks as f64 / in_wall / 1e3);
    println!("\nLockstep, full loop (simulated stage + Ch. 7 PID), {LOCKSTEP_S} s simulated:\n");
    println!("| loop | ticks | tick rate | vs 199.6 kHz |");
    println!("|---|---|---|---|");
    println!(
        "| plant and controller processes over iceoryx2 | {ticks} | {hil_khz:.1} kHz | {:.2}× |",
        hil_khz / 199.6
    );
    println!(
        "| in process (`servo run`, baseline) | {in_ticks} | {in_khz:.1} kHz | {:.2}× |",
        in_khz / 199.6
    );
    let json = serde_json::json!({
        "round_trip_ns": { "cache_line": floor, "bare_iceoryx2": bare, "ours": ours, "unix_socket": sock },
        "ours_over_bare_median": ratio,
        "lockstep_khz": { "processes": hil_khz, "in_process": in_khz },
    });
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/ipc-bench.json");
    std::fs::write(&out, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    println!("\nwrote {}", out.display());
}
