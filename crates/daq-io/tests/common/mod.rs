//! Shared by the transport tests.

use daq_io::ipc::{Endpoint, Publisher, Tap};
use daq_io::{flags, Backend, Health, Sensor, Truth};
use std::time::Duration;

/// A first-order plant y⁺ = 0.9 y + 0.1 u with a deterministic pseudo-noise term.
#[derive(Default)]
pub struct Lag {
    y: f64,
    k: u64,
    last_u: f64,
}

impl Backend for Lag {
    fn step(&mut self, dac_v: f64) -> Sensor {
        self.k += 1;
        self.last_u = dac_v;
        self.y = 0.9 * self.y + 0.1 * dac_v + 1e-3 * ((self.k * 2654435761) % 1000) as f64;
        Sensor {
            time_s: self.k as f64 * 1e-5,
            gap_v: self.y,
            ..Default::default()
        }
    }
    fn truth(&self) -> Option<Truth> {
        Some(Truth {
            dac_v: self.last_u,
            tool_m: self.y,
            ..Default::default()
        })
    }
}

/// A run prefix unique to this test process.
pub fn prefix(tag: &str) -> String {
    format!("test-{tag}-{}", std::process::id())
}

/// A recorder's ports on run `ep`: its tap, then its progress publisher (made after the tap,
/// as `servo record` does: its presence tells a plant the recorder listens).
pub fn recorder_tap(ep: &Endpoint) -> (Tap, Publisher<Health>) {
    let tap = Tap::new(ep).unwrap();
    let progress = ep.publisher(daq_io::ipc::leaf::RECORDED).unwrap();
    (tap, progress)
}

/// Every truth record of the run up to its END block; then leaves (so the plant can finish).
pub fn truth_until_end(tap: Tap) -> Vec<Truth> {
    let mut truth = Vec::new();
    loop {
        match daq_io::ipc::take(&tap.truth) {
            Some(b) => {
                truth.extend_from_slice(&b.ticks[..b.count as usize]);
                if b.flags & flags::END != 0 {
                    return truth;
                }
            }
            None => std::thread::sleep(Duration::from_millis(1)),
        }
    }
}
