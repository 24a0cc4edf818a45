//! Real-time pacing (own test binary: only the plant and controller threads spin here, as
//! in a real deployment; the other transport tests would compete for the two cores).

use daq_io::ipc::{ControllerLink, Endpoint, Tap};
use daq_io::serve::{serve, Pacing, ServeOptions};
use daq_io::{flags, Command, Daq};
use std::sync::atomic::AtomicUsize;
use std::time::Duration;

mod common;
use common::{prefix, truth_until_end, Lag};

/// One attempt; `None` when the machine stalled the controller thread past the peer timeout
/// before it meant to go silent (a correct fault, but not the scenario under test).
fn attempt(n: u32) -> Option<()> {
    let p = prefix(&format!("rt-silent-{n}"));
    let p2 = p.clone();
    let period = 1e-5;
    let ep = Endpoint::open(&p, "recorder").unwrap();
    let tap = Tap::new(&ep).unwrap();
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let opts = ServeOptions::new(1_000_000, period, Pacing::RealTime);
        serve(&ep, &mut Lag::default(), &opts, &AtomicUsize::new(0)).unwrap()
    });
    // Answers the first 1000 samples with 2 V, then goes silent (as if killed).
    let cep = Endpoint::open(&p, "controller").unwrap();
    let mut link =
        ControllerLink::new(&cep, Duration::from_secs(10), Duration::from_secs(1)).unwrap();
    let mut last = 0;
    while last < 999 {
        let s = link.read().ok()?;
        if s.flags & flags::END != 0 {
            // Declared lost early: let the plant finish, then report the stall.
            drop(tap);
            let report = plant.join().unwrap();
            assert!(report.fault_tick.is_some_and(|k| k <= 1000));
            return None;
        }
        last = s.seq;
        link.write(Command {
            seq: s.seq,
            dac_v: 2.0,
            ..Default::default()
        })
        .unwrap();
    }
    let truth = truth_until_end(tap);
    let report = plant.join().unwrap();
    let fault = report.fault_tick.expect("controller declared lost");
    // The last tick that got its command (the DAC held 2 V); the silence starts after it.
    let answered = truth
        .iter()
        .rposition(|t| t.flags & flags::OVERRUN == 0 && t.dac_v == 2.0)
        .unwrap() as u64;
    let silent_s = (fault - answered) as f64 * period;
    assert!(
        silent_s <= 0.5e-3 + 3.0 * period,
        "declared lost {silent_s} s after the last command"
    );
    assert!(truth[fault as usize..]
        .iter()
        .all(|t| t.dac_v == 0.0 && t.flags & flags::FAULT_PEER_LOST != 0));
    assert_eq!(report.ticks, fault + (2e-3 / period) as u64);
    Some(())
}

/// A shared 2-core machine can deschedule the controller thread for more than 0.5 ms (a
/// correct lost-controller fault); such attempts are repeated, up to twenty.
#[test]
fn real_time_plant_drives_zero_within_half_a_millisecond_of_the_last_command() {
    let clean = (0..20).find_map(attempt);
    assert!(clean.is_some(), "twenty attempts, each stalled past 0.5 ms");
}
