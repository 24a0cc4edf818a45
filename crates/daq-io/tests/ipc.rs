//! The iceoryx2 transport against the in-process one: the same backend and the same controller
//! law give bit-identical sequences; a silent controller puts the plant in the safe state.

use daq_io::ipc::{ControllerLink, Endpoint};
use daq_io::serve::{serve, Pacing, ServeOptions, ServeReport};
use daq_io::{flags, Command, Daq, InProcess};

use crate::common;
use common::{prefix, recorder_tap, truth_until_end, Lag};
use std::sync::atomic::AtomicUsize;
use std::time::Duration;

/// A PI law on the gap reading; returns the commands it sent.
fn control(daq: &mut impl Daq) -> Vec<f64> {
    let (mut integral, mut out) = (0.0, Vec::new());
    loop {
        let s = daq.read().expect("sample");
        if s.flags & flags::END != 0 {
            return out;
        }
        let e = 1.0 - s.gap_v;
        integral += 0.05 * e;
        let u = 0.8 * e + integral;
        out.push(u);
        daq.write(Command {
            seq: s.seq,
            dac_v: u,
            ..Default::default()
        })
        .unwrap();
    }
}

#[test]
fn lockstep_over_shared_memory_equals_in_process() {
    let ticks = 20_000;
    let expected = control(&mut InProcess::new(Lag::default(), ticks));
    let p = prefix("lockstep");
    let p2 = p.clone();
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let mut opts = ServeOptions::new(ticks, 1e-5, Pacing::Lockstep);
        opts.wait_for_recorder = false;
        serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
    });
    let ep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_secs(10), Duration::from_secs(1)).unwrap();
    let got = control(&mut link);
    let report = plant.join().unwrap();
    assert_eq!(got.len(), expected.len());
    assert!(got
        .iter()
        .zip(&expected)
        .all(|(a, b)| a.to_bits() == b.to_bits()));
    assert_eq!(
        (report.ticks, report.overruns, report.faults),
        (ticks, 0, 0)
    );
    assert_eq!(report.latency.count, ticks);
}

#[test]
fn silent_controller_drives_zero_and_flags_the_fault() {
    let p = prefix("silent");
    let p2 = p.clone();
    let ep = Endpoint::open(&p, "recorder").unwrap();
    let (tap, _progress) = recorder_tap(&ep);
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let mut opts = ServeOptions::new(1_000_000, 1e-5, Pacing::Lockstep);
        // Long enough that a starved test thread is not taken for a silent controller.
        opts.peer_timeout = Duration::from_millis(500);
        opts.safe_ticks = 50;
        serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
    });
    // A controller that answers 100 ticks with 2 V, then goes silent.
    let cep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&cep, Duration::from_secs(10), Duration::from_secs(10)).unwrap();
    for _ in 0..100 {
        let s = link.read().unwrap();
        link.write(Command {
            seq: s.seq,
            dac_v: 2.0,
            ..Default::default()
        })
        .unwrap();
    }
    let truth = truth_until_end(tap);
    let report = plant.join().unwrap();
    assert_eq!(report.fault_tick, Some(100));
    assert_eq!(report.faults, flags::FAULT_PEER_LOST);
    assert_eq!(report.ticks, 150);
    assert_eq!(truth.len(), 150);
    assert!(truth[..100].iter().all(|t| t.dac_v == 2.0 && t.flags == 0));
    assert!(truth[100..]
        .iter()
        .all(|t| t.dac_v == 0.0 && t.flags & flags::FAULT_PEER_LOST != 0));
}

#[test]
fn a_plant_told_to_wait_starts_on_the_control_plane_start() {
    let ticks = 1000;
    let p = prefix("start");
    let p2 = p.clone();
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let mut opts = ServeOptions::new(ticks, 1e-5, Pacing::Lockstep);
        opts.wait_for_recorder = false;
        opts.wait_for_start = true;
        serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
    });
    let ep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_millis(200), Duration::from_secs(10)).unwrap();
    assert!(
        matches!(link.read(), Err(daq_io::DaqError::PlantLost { seq: 0, .. })),
        "no tick before START"
    );
    // The sender lives on: samples of a publisher that is gone are not delivered.
    let sender = daq_io::ipc::ControlSender::new(&ep).unwrap();
    sender
        .send(daq_io::Control {
            command: daq_io::contract::command::START,
            ..Default::default()
        })
        .unwrap();
    assert_eq!(control(&mut link).len() as u64, ticks);
    assert_eq!(plant.join().unwrap().ticks, ticks);
}

/// A peer of another contract version (here an iceoryx2 node named as a v2 plant would name
/// it) is refused at connect, with both versions named; a second process in the same role on
/// the same prefix is refused as a second run.
#[test]
fn a_peer_of_another_contract_version_is_refused_at_connect() {
    use iceoryx2::prelude::*;
    let p = prefix("version");
    let old = NodeBuilder::new()
        .name(&NodeName::new(&format!("fts-servo/v2/{p}/plant")).unwrap())
        .create::<ipc::Service>()
        .unwrap();
    let e = Endpoint::open(&p, "controller").err().expect("refused");
    let msg = e.to_string();
    assert!(
        msg.contains("contract mismatch")
            && msg.contains("contract v2")
            && msg.contains(&format!("v{}", daq_io::CONTRACT_VERSION))
            && msg.contains(&format!("pid {}", std::process::id())),
        "{msg}"
    );
    drop(old);
    // Gone: the same join succeeds; a second controller is a second run.
    let first = Endpoint::open(&p, "controller").unwrap();
    let e = Endpoint::open(&p, "controller").err().expect("refused");
    assert!(e.to_string().contains("is in use by a live run"), "{e}");
    assert_eq!(first.peers(), vec![]);
}

/// The controller keeps to the run of its first sample: a sample stamped with another run id
/// (a plant restarted on the prefix, or a stray publisher) is refused with both ids.
#[test]
fn a_sample_of_another_run_is_refused() {
    let p = prefix("runid");
    let plant = Endpoint::open(&p, "plant").unwrap();
    let sensor = plant
        .publisher::<daq_io::Sensor>(daq_io::ipc::leaf::SENSOR)
        .unwrap();
    let ep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_secs(30), Duration::from_secs(30)).unwrap();
    let sample = |seq, run_id| daq_io::Sensor {
        seq,
        run_id,
        ..Default::default()
    };
    daq_io::ipc::connect(&sensor);
    assert!(daq_io::ipc::send(&sensor, sample(0, 0xA11CE)));
    assert_eq!(link.read().unwrap().seq, 0);
    assert_eq!(link.run_id(), 0xA11CE);
    assert!(daq_io::ipc::send(&sensor, sample(1, 0xB0B)));
    match link.read() {
        Err(daq_io::DaqError::ForeignRun { expected, got }) => {
            assert_eq!((expected, got), (0xA11CE, 0xB0B))
        }
        other => panic!("{other:?}"),
    }
}

/// A plant stamps every sample with one nonzero run id, new for every run.
#[test]
fn every_run_gets_its_own_id() {
    let ids: Vec<u64> = (0..2)
        .map(|i| {
            let p = prefix(&format!("ids{i}"));
            let p2 = p.clone();
            let plant = std::thread::spawn(move || {
                let ep = Endpoint::open(&p2, "plant").unwrap();
                let mut opts = ServeOptions::new(100, 1e-5, Pacing::Lockstep);
                opts.wait_for_recorder = false;
                serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
            });
            let ep = Endpoint::open(&p, "controller").unwrap();
            let mut link =
                ControllerLink::new(&ep, Duration::from_secs(30), Duration::from_secs(30)).unwrap();
            let first = control(&mut link);
            assert_eq!(first.len(), 100);
            let report = plant.join().unwrap();
            assert_eq!(link.run_id(), report.run_id);
            report.run_id
        })
        .collect();
    assert!(ids[0] != 0 && ids[1] != 0 && ids[0] != ids[1], "{ids:x?}");
}

/// A backend with a clock of its own: each tick's edge lies a scripted time in the past.
struct Clocked {
    lag: Lag,
    late_ns: Vec<u64>,
}

impl daq_io::Backend for Clocked {
    fn step(&mut self, dac_v: f64) -> daq_io::Sensor {
        self.lag.step(dac_v)
    }
    fn wait_for_tick(&mut self, k: u64) -> Option<u64> {
        let late = self.late_ns[k as usize % self.late_ns.len()];
        Some(daq_io::clock::monotonic_ns() - late)
    }
}

/// The plant as the clock: the server measures each tick's start against its backend's clock
/// edge. Every edge here is a known time in the past (1–100 µs, twenty ticks each), so the
/// lateness percentiles are the reference's plus the few ns between the two clock reads (a
/// machine that preempts the server in between adds to one tick: at most one 1 µs step).
#[test]
fn the_server_measures_lateness_against_the_backends_own_clock() {
    let ticks = 2_000u64;
    let late_ns: Vec<u64> = (0..=ticks)
        .map(|k| ((k * 7919) % 100 + 1) * 1_000)
        .collect();
    let p = prefix("own-clock");
    let p2 = p.clone();
    let script = late_ns.clone();
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let mut opts = ServeOptions::new(ticks, 1e-5, Pacing::Lockstep);
        opts.wait_for_recorder = false;
        let mut hw = Clocked {
            lag: Lag::default(),
            late_ns: script,
        };
        serve(&ep, &mut hw, &opts, &AtomicUsize::new(0)).unwrap()
    });
    let ep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_secs(10), Duration::from_secs(1)).unwrap();
    control(&mut link);
    let l = plant.join().unwrap().lateness;
    // Ticks 1.. are timed (tick 0 is the untimed start-up exchange).
    let mut reference = late_ns[1..ticks as usize].to_vec();
    reference.sort_unstable();
    let n = reference.len();
    assert_eq!(l.count, n as u64);
    let at = |q: f64| reference[((q * n as f64).ceil() as usize).clamp(1, n) - 1];
    for (q, got) in [(0.5, l.p50_ns), (0.99, l.p99_ns), (0.999, l.p999_ns)] {
        let want = at(q);
        assert!(
            got + 10 >= want && got <= want + 1_010,
            "q {q}: {got} ns against {want} ns"
        );
    }
    assert!(l.min_ns >= 1_000 && l.max_ns >= 100_000, "{l:?}");
}

/// A recorder that takes every truth block as it comes but (if `reports`) says how many ticks
/// it has taken only once the plant announced a hold for it — a recorder behind by more than
/// the plant allows, whatever the two threads' speeds; what it received.
fn late_reporting_recorder(ep: &Endpoint, reports: bool) -> Vec<daq_io::Truth> {
    use daq_io::contract::{role, state};
    let (tap, progress) = recorder_tap(ep);
    let mut truth: Vec<daq_io::Truth> = Vec::new();
    let mut held = false;
    let mut reported = None;
    loop {
        while let Some(h) = daq_io::ipc::take(&tap.health) {
            held |= h.role == role::PLANT && h.state == state::HELD_FOR_RECORDER;
        }
        let block = daq_io::ipc::take(&tap.truth);
        if let Some(b) = &block {
            truth.extend_from_slice(&b.ticks[..b.count as usize]);
        }
        // Reports what it has taken once the plant holds, even when it had already taken
        // every block before it saw the hold (no new block comes while the plant holds).
        let taken = truth.last().map_or(0, |t| t.seq + 1);
        if reports && held && reported != Some(taken) {
            let h = daq_io::Health {
                role: role::RECORDER,
                ticks: taken,
                ..Default::default()
            };
            daq_io::ipc::send(&progress, h);
            reported = Some(taken);
        }
        match block {
            Some(b) if b.flags & flags::END != 0 => return truth,
            Some(_) => {}
            None => std::thread::sleep(Duration::from_micros(200)),
        }
    }
}

/// A lockstep plant, its PI controller and a late-reporting recorder (reporting or not): the
/// plant's report and what the recorder received.
fn lockstep_with_slow_recorder(tag: &str, reports: bool) -> (ServeReport, Vec<daq_io::Truth>) {
    // Two queues' worth: the plant reaches the recorder's allowance (half a queue) early.
    let ticks = 2 * 1024 * daq_io::BLOCK_TICKS as u64;
    let p = prefix(tag);
    let p2 = p.clone();
    let rep = Endpoint::open(&p, "recorder").unwrap();
    let recorder = std::thread::spawn(move || late_reporting_recorder(&rep, reports));
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let opts = ServeOptions::new(ticks, 1e-5, Pacing::Lockstep);
        serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
    });
    let ep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&ep, Duration::from_secs(10), Duration::from_secs(5)).unwrap();
    control(&mut link);
    (plant.join().unwrap(), recorder.join().unwrap())
}

#[test]
fn a_lockstep_plant_holds_for_a_slow_recorder_and_nothing_is_lost() {
    let (report, truth) = lockstep_with_slow_recorder("paced", true);
    assert_eq!(report.faults, 0);
    assert!(!report.recorder_silent);
    assert!(report.recorder_held_s > 0.0, "{report:?}");
    assert_eq!(truth.len() as u64, report.ticks);
    assert!(truth.iter().enumerate().all(|(i, t)| t.seq == i as u64));
}

#[test]
fn a_recorder_that_does_not_report_is_waited_for_only_once() {
    let (report, truth) = lockstep_with_slow_recorder("unpaced", false);
    assert_eq!(report.faults, 0);
    assert!(report.recorder_silent, "{report:?}");
    // One hold of the patience, then the plant ran free (unpaced, what this recorder still
    // got depends on the threads' speeds).
    let patience = daq_io::recorder_pace::PATIENCE.as_secs_f64();
    assert!(report.recorder_held_s >= patience, "{report:?}");
    assert!(!truth.is_empty() && truth.len() as u64 <= report.ticks);
}
