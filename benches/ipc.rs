//! HIL transport bench (a dedicated binary: two processes, busy polling). Prints and writes
//! `target/ipc-bench.json`:
//! - round trip plant → controller → plant over iceoryx2 (a `Sensor` out, a `Command` back),
//!   10⁶ exchanges after 10⁴ warm-up, min/median/p99/p99.9/max;
//! - the baseline transport in the same run: a Unix stream socket ping-pong (blocking reads,
//!   the usual choice), same message sizes;
//! - sustained lockstep tick rate of the full loop across processes (simulated stage +
//!   Chapter 7 PID, `runner::hil`), against the in-process loop (`servo run`) in the same run.
//!
//! Usage: `cargo bench --bench ipc` (the binary re-executes itself as the peer process).

use daq_io::ipc::{leaf, poll_until, ControllerLink, Endpoint};
use daq_io::{Command, Daq, LatencyHistogram, Sensor};
use runner::config::Loaded;
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::{Child, Command as Process};
use std::time::{Duration, Instant};

const ROLE: &str = "FTS_IPC_BENCH_ROLE";
const EXCHANGES: u64 = 1_000_000;
const WARMUP: u64 = 10_000;
const SOCKET_EXCHANGES: u64 = 200_000;
const LOCKSTEP_S: f64 = 5.0;

fn peer(role: &str, arg: &str) -> Child {
    Process::new(std::env::current_exe().unwrap())
        .env(ROLE, role)
        .arg(arg)
        .spawn()
        .expect("re-executing the bench as its peer")
}

fn arg() -> String {
    std::env::args().nth(1).expect("peer argument")
}

/// Peer: answers every sensor sample with a command echoing its sequence number.
fn echo_iceoryx2(prefix: &str) {
    let ep = Endpoint::open(prefix, "echo").unwrap();
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
    }
}

fn round_trip_iceoryx2() -> LatencyHistogram {
    let prefix = format!("bench-rt-{}", std::process::id());
    let ep = Endpoint::open(&prefix, "driver").unwrap();
    let sensor = ep.publisher::<Sensor>(leaf::SENSOR).unwrap();
    let command = ep.subscriber::<Command>(leaf::COMMAND).unwrap();
    let service = ep.service::<Sensor>(leaf::SENSOR).unwrap();
    let mut child = peer("echo", &prefix);
    use iceoryx2::prelude::PortFactory;
    while service.dynamic_config().number_of_subscribers() == 0 {
        std::thread::sleep(Duration::from_millis(1));
    }
    let mut h = LatencyHistogram::new();
    for k in 0..WARMUP + EXCHANGES {
        let t = Instant::now();
        daq_io::ipc::send(
            &sensor,
            Sensor {
                seq: k,
                gap_v: k as f64,
                ..Default::default()
            },
        );
        poll_until(&command, t + Duration::from_secs(5), |c| c.seq == k).expect("echo");
        if k >= WARMUP {
            h.record(t.elapsed().as_nanos() as u64);
        }
    }
    daq_io::ipc::send(
        &sensor,
        Sensor {
            seq: WARMUP + EXCHANGES,
            flags: daq_io::flags::END,
            ..Default::default()
        },
    );
    child.wait().unwrap();
    h
}

const MSG: usize = std::mem::size_of::<Sensor>();

fn echo_socket(path: &str) {
    let mut s = UnixStream::connect(path).unwrap();
    let mut buf = [0u8; MSG];
    while s.read_exact(&mut buf).is_ok() {
        s.write_all(&buf[..std::mem::size_of::<Command>()]).unwrap();
    }
}

fn round_trip_socket() -> LatencyHistogram {
    let path = std::env::temp_dir().join(format!("fts-bench-{}.sock", std::process::id()));
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path).unwrap();
    let mut child = peer("socket", path.to_str().unwrap());
    let (mut s, _) = listener.accept().unwrap();
    let (out, mut back) = ([7u8; MSG], [0u8; std::mem::size_of::<Command>()]);
    let mut h = LatencyHistogram::new();
    for k in 0..WARMUP + SOCKET_EXCHANGES {
        let t = Instant::now();
        s.write_all(&out).unwrap();
        s.read_exact(&mut back).unwrap();
        if k >= WARMUP {
            h.record(t.elapsed().as_nanos() as u64);
        }
    }
    drop(s);
    child.wait().unwrap();
    let _ = std::fs::remove_file(&path);
    h
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
    let start = Instant::now();
    let s = runner::run::run_to_end(&plan).unwrap();
    (
        (r.ticks, r.wall_s),
        (s.ticks, start.elapsed().as_secs_f64()),
    )
}

fn row(name: &str, h: &LatencyHistogram) -> serde_json::Value {
    let l = h.summary();
    let us = |ns: u64| ns as f64 * 1e-3;
    println!(
        "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} |",
        l.count,
        us(l.min_ns),
        us(l.p50_ns),
        us(l.p99_ns),
        us(l.p999_ns),
        us(l.max_ns)
    );
    serde_json::to_value(l).unwrap()
}

fn main() {
    match std::env::var(ROLE).as_deref() {
        Ok("echo") => return echo_iceoryx2(&arg()),
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
    println!("Round trip plant → controller → plant, two processes, µs:\n");
    println!("| transport | exchanges | min | median | p99 | p99.9 | max |");
    println!("|---|---|---|---|---|---|---|");
    let ice = row(
        "iceoryx2 0.10 publish-subscribe, busy polling",
        &round_trip_iceoryx2(),
    );
    let sock = row(
        "Unix stream socket, blocking reads (baseline)",
        &round_trip_socket(),
    );
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
        "round_trip_ns": { "iceoryx2": ice, "unix_socket": sock },
        "lockstep_khz": { "processes": hil_khz, "in_process": in_khz },
    });
    let out = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/ipc-bench.json");
    std::fs::write(&out, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    println!("\nwrote {}", out.display());
}
