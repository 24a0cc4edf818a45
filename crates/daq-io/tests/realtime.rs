//! Real-time pacing (own test binary: only the plant and controller threads spin here, as
//! in a real deployment; the other transport tests would compete for the two cores).

use daq_io::ipc::{ControllerLink, Endpoint};
use daq_io::serve::{serve, Pacing, ServeOptions};
use daq_io::{flags, Command, Daq};
use std::sync::atomic::AtomicUsize;
use std::time::Duration;

use crate::common;
use common::{prefix, recorder_tap, truth_until_end, Lag};

/// Peer timeout of the test, s: long against any scheduling stall of a busy machine, so only
/// the controller's real silence trips it (how fast the default 0.5 ms trips is a wall-clock
/// measurement, not a test).
const PEER_TIMEOUT: Duration = Duration::from_millis(50);

/// One attempt; `None` when the machine stalled the controller thread past the peer timeout
/// before it meant to go silent (a correct fault, but not the scenario under test).
fn attempt(n: u32) -> Option<()> {
    let p = prefix(&format!("rt-silent-{n}"));
    let p2 = p.clone();
    let period = 1e-5;
    let ep = Endpoint::open(&p, "recorder").unwrap();
    let (tap, _progress) = recorder_tap(&ep);
    let plant = std::thread::spawn(move || {
        let ep = Endpoint::open(&p2, "plant").unwrap();
        let mut opts = ServeOptions::new(1_000_000, period, Pacing::RealTime);
        opts.peer_timeout = PEER_TIMEOUT;
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
    assert!(
        fault > answered,
        "declared lost at {fault}, before the last command {answered}"
    );
    assert!(truth[fault as usize..]
        .iter()
        .all(|t| t.dac_v == 0.0 && t.flags & flags::FAULT_PEER_LOST != 0));
    assert_eq!(report.ticks, fault + (2e-3 / period) as u64);
    Some(())
}

/// A real-time plant whose controller goes silent declares it lost after the peer timeout,
/// drives 0 V with the fault flag on every later tick and ends the run 2 ms later. A machine
/// that stalls the controller past the timeout before it meant to go silent makes a correct
/// fault of its own; such attempts are repeated, up to twenty.
#[test]
fn real_time_plant_drives_zero_after_the_controller_goes_silent() {
    let clean = (0..20).find_map(attempt);
    assert!(
        clean.is_some(),
        "twenty attempts, each stalled past {PEER_TIMEOUT:?}"
    );
}
