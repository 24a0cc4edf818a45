//! A served loop answers the control plane as `servo ctl` speaks it: gain changes inside the
//! stored range applied at a tick (and acknowledged with it), outside it refused; controller
//! files loaded only when made for the loop's plant and carrying their offline check; STOP
//! handed to the daemon; telemetry published until the run's end.

#![cfg(feature = "serve")]

use daq_io::contract::command;
use daq_io::ipc::{leaf, take, take_waiting, ControlSender, Endpoint, Tap};
use daq_io::{ack_status, flags, Ack, Control, ControllerLoad, Sensor};
use servo_config::{
    controller_toml, deployment_toml, ControllerSpec, Deployment, MadeFor, Stability,
};
use servo_runtime::Servo;
use std::time::Duration;

/// The bound `await_subscriber` asks for: an hour, so a busy machine never meets it (a test
/// that hung would be stopped by the harness, not by a clock here).
const LISTEN_BOUND: Duration = Duration::from_secs(3600);

fn made_for(plant: &str) -> MadeFor {
    MadeFor {
        tool: "fts-servo test".into(),
        plant_sha256: plant.into(),
        stage: "light".into(),
        servo_rate_hz: 199_600.0,
    }
}

/// A stability record for `controller` on the thesis prototype's loop, sealed to it.
fn stability(controller: &ControllerSpec) -> Stability {
    let d = Deployment::thesis_prototype();
    Stability {
        spectral_radius: 0.9999,
        unstable_below: 0.1,
        unstable_above: 5.0,
        sha256: Default::default(),
    }
    .sealed(d.servo_rate_hz, &d.stage, controller)
}

/// A `[controller]` file made for `plant`, with or without its offline check.
fn fragment(plant: &str, checked: bool) -> String {
    let mut c = ControllerSpec::default();
    c.pid.kp *= 0.9;
    controller_toml(
        &c,
        Some(&made_for(plant)),
        checked.then(|| stability(&c)).as_ref(),
    )
}

/// What `servo ctl` does: send, then wait for the acknowledgement of request `id`.
struct Peer {
    _ep: Endpoint,
    tap: Tap,
    control: ControlSender,
    loads: daq_io::ipc::Publisher<ControllerLoad>,
    blocks: u64,
    end_seen: bool,
}

impl Peer {
    fn new(prefix: &str) -> Self {
        let ep = Endpoint::open(prefix, "ctl-test").unwrap();
        let tap = Tap::new(&ep).unwrap();
        let control = ControlSender::new(&ep).unwrap();
        let loads = ep.publisher(leaf::CONTROLLER_LOAD).unwrap();
        for ready in [
            ep.await_subscriber::<Control>(leaf::CONTROL, LISTEN_BOUND),
            ep.await_subscriber::<ControllerLoad>(leaf::CONTROLLER_LOAD, LISTEN_BOUND),
        ] {
            assert!(ready.unwrap(), "the loop did not listen");
        }
        Peer {
            _ep: ep,
            tap,
            control,
            loads,
            blocks: 0,
            end_seen: false,
        }
    }

    fn drain(&mut self) {
        // What is there now: the loop publishes as fast as this takes.
        for b in take_waiting(&self.tap.telemetry) {
            self.blocks += 1;
            self.end_seen |= b.flags & flags::END != 0;
        }
    }

    /// The acknowledgement of request `id` (no clock: the loop answers every request).
    fn ack(&mut self, id: u64) -> Ack {
        loop {
            self.drain();
            if let Some(a) = take(&self.tap.ack).filter(|a| a.id == id) {
                return a;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    fn control(&mut self, id: u64, command: u32, value: f64) -> Ack {
        self.control
            .send(Control {
                command,
                value,
                id,
                ..Default::default()
            })
            .unwrap();
        self.ack(id)
    }

    fn load(&mut self, id: u64, file: &str) -> Ack {
        daq_io::ipc::send(
            &self.loads,
            ControllerLoad::new(id, file.as_bytes()).unwrap(),
        );
        self.ack(id)
    }
}

#[test]
fn a_served_loop_answers_the_control_plane() {
    let prefix = format!("rt-serve-{}", std::process::id());
    let mut d = Deployment::thesis_prototype();
    d.stability = Some(stability(&d.controller));
    let text = deployment_toml(&d, Some(&made_for("plant-a")), "test");
    let mut servo = Servo::from_toml(&text).unwrap();
    servo.serve(&prefix).unwrap();
    let peer = {
        let prefix = prefix.clone();
        std::thread::spawn(move || {
            let mut p = Peer::new(&prefix);
            let acks = [
                p.control(1, command::SET_GAIN_SCALE, 100.0),
                p.control(2, command::SET_GAIN_SCALE, 0.8),
                p.control(3, command::SET_GAIN_SCALE, f64::NAN),
                p.load(4, "not toml ["),
                p.load(5, &fragment("plant-b", true)),
                p.load(6, &fragment("plant-a", false)),
                p.load(7, &fragment("plant-a", true)),
                p.control(8, command::STOP, 0.0),
            ];
            // Every telemetry block through to the end of the run (the loop lingers for us).
            while !p.end_seen {
                p.drain();
                std::thread::sleep(Duration::from_millis(1));
            }
            (p.blocks, p.end_seen, acks)
        })
    };
    let mut sample = Sensor {
        run_id: 42,
        ..Default::default()
    };
    let mut k = 0;
    while servo.status().stop.is_none() {
        sample.seq = k;
        servo.tick(&sample);
        k += 1;
    }
    let status = servo.status();
    servo.close(0);
    let (blocks, end_seen, acks) = peer.join().unwrap();
    let statuses: Vec<u32> = acks.iter().map(|a| a.status).collect();
    assert_eq!(
        statuses,
        [
            ack_status::REFUSED_MARGIN,
            ack_status::APPLIED,
            ack_status::REFUSED_INVALID,
            ack_status::REFUSED_INVALID,
            ack_status::REFUSED_PROVENANCE,
            ack_status::REFUSED_MARGIN,
            ack_status::APPLIED,
            ack_status::APPLIED,
        ]
    );
    // The range acknowledged is the stored one with its 2× margin.
    assert_eq!((acks[0].low, acks[0].high), (0.2, 2.5));
    // Applied at a tick the loop ran, and in force from then on.
    assert!(acks[1].tick > 0 && acks[1].tick <= k);
    assert_eq!(status.gain_scale, 0.8);
    assert_eq!(status.handovers, 1);
    assert!(acks[6].tick >= acks[1].tick && acks[6].value == 0.9999);
    assert_eq!(status.stop, Some(daq_io::stop_cause::CONTROL));
    // Telemetry flowed to the end of the run; an unpaced loop (here ~40× real time) outruns its
    // service thread, and the ring drops what it cannot hold rather than wait — counted.
    assert!(end_seen && blocks > 0, "{blocks} blocks for {k} ticks");
    assert!(status.telemetry_dropped <= k);
}

#[test]
fn a_second_loop_on_a_prefix_in_use_is_refused() {
    let prefix = format!("rt-twice-{}", std::process::id());
    let mut a = Servo::new(&Deployment::thesis_prototype()).unwrap();
    a.serve(&prefix).unwrap();
    let mut b = Servo::new(&Deployment::thesis_prototype()).unwrap();
    let e = b.serve(&prefix).unwrap_err().to_string();
    assert!(e.contains("in use"), "{e}");
    a.close(0);
}
