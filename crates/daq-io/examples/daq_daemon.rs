//! How a host DAQ daemon embeds daq-io: implement [`Backend`] for the ADC/DAC hardware and
//! hand it to [`serve`]; any controller that speaks the sample contract (`servo controller`,
//! or your own) then closes the loop through shared memory, with the daemon keeping the
//! safety duties (pacing, overruns, zero current when the controller is lost).
//!
//! The hardware here is a fake so the example runs anywhere: a 16-bit ADC and an 18-bit DAC
//! (±10 V, plant-sim's converters) around an 800 Hz, ζ = 0.05 mass-spring stage read by a 1 V/µm gap sensor.
//!
//! The plant as the clock: with `--clock adc` the fake ADC has a sample clock of its own and
//! `Backend::wait_for_tick` blocks until each conversion is done (as a driver's blocking read
//! or an interrupt would); `serve` paces on it and measures its lateness against it. Without
//! it, `serve` paces on the wall clock (`--realtime`) or runs in lockstep.
//!
//! A practice stage for the measure → identify → design workflow: with `--practice-seed N`
//! the daemon serves the thesis stage with its Table 5-2 parameters drawn from the seed and a
//! sensor-mount resonance the identification model does not contain
//! (`plant_sim::practice`); the client is never told the draw. `--reveal FILE` writes it (TOML)
//! when the run ends, to grade the identification against.
//!
//! ```text
//! cargo run --release -p daq-io --example daq_daemon -- --prefix lab --realtime
//! servo controller --prefix lab          # in another terminal (or your own controller)
//! cargo run --release -p daq-io --example daq_daemon -- --prefix lab --demo   # both, here
//! cargo run --release -p daq-io --example daq_daemon -- --prefix lab --demo --clock adc
//! cargo run --release -p daq-io --example daq_daemon -- --prefix lab --practice-seed 42 --seconds 30
//! servo frf --prefix lab --loop open --points 80 --from 20 --to 10000   # then servo identify
//! cargo run --release -p daq-io --example daq_daemon -- --prefix lab --practice-seed 42 --seconds 30 --wait-recorder
//! ```

use daq_io::clock::{monotonic_ns, Wait};
use daq_io::ipc::{ControllerLink, Endpoint};
use daq_io::serve::{serve, Pacing, ServeOptions};
use daq_io::{flags, Backend, Command, Daq, Sensor};
use plant_sim::convert::Quantizer;
use plant_sim::practice::PracticeStage;
use plant_sim::PlantParams;
use std::sync::atomic::AtomicUsize;
use std::time::Duration;

/// Servo rate of the daemon, Hz.
const RATE_HZ: f64 = 199_600.0;

/// The fake hardware: DAC → amplifier/motor (1 N/V) → stage → gap sensor → ADC.
struct FakeHardware {
    adc: Quantizer,
    dac: Quantizer,
    x_m: f64,
    v_m_s: f64,
    t_s: f64,
    /// The ADC's own sample clock (`--clock adc`): when conversions complete, ns.
    adc_clock: Option<AdcClock>,
}

/// A free-running conversion clock: tick k's conversion is done at `first_ns + (k − 1)·T`.
struct AdcClock {
    first_ns: u64,
    period_ns: u64,
}

impl FakeHardware {
    const MASS_KG: f64 = 0.075;
    const F_N_HZ: f64 = 800.0;
    const ZETA: f64 = 0.05;
    const SENSOR_V_PER_M: f64 = 1e6;

    fn new(own_clock: bool) -> Self {
        FakeHardware {
            adc: Quantizer::new(16, 10.0),
            dac: Quantizer::new(18, 10.0),
            x_m: 0.0,
            v_m_s: 0.0,
            t_s: 0.0,
            adc_clock: own_clock.then_some(AdcClock {
                first_ns: 0,
                period_ns: (1e9 / RATE_HZ).round() as u64,
            }),
        }
    }
}

impl Backend for FakeHardware {
    /// Blocks until the conversion of tick `k` is done (the clock starts with tick 1: tick 0
    /// is the untimed start-up exchange) and returns when it was.
    fn wait_for_tick(&mut self, k: u64) -> Option<u64> {
        let clock = self.adc_clock.as_mut()?;
        if k <= 1 {
            clock.first_ns = monotonic_ns();
            return Some(clock.first_ns);
        }
        let edge = clock.first_ns + (k - 1) * clock.period_ns;
        Wait::Spin.until(edge);
        Some(edge)
    }

    fn step(&mut self, dac_v: f64) -> Sensor {
        let (out_v, dac_clipped) = self.dac.convert(dac_v);
        let w = 2.0 * std::f64::consts::PI * Self::F_N_HZ;
        let dt = 1.0 / RATE_HZ;
        // Semi-implicit Euler is plenty for a stand-in (w·dt = 0.025).
        let a = out_v / Self::MASS_KG - 2.0 * Self::ZETA * w * self.v_m_s - w * w * self.x_m;
        self.v_m_s += a * dt;
        self.x_m += self.v_m_s * dt;
        self.t_s += dt;
        let (gap_v, adc_clipped) = self.adc.convert(self.x_m * Self::SENSOR_V_PER_M);
        Sensor {
            time_s: self.t_s,
            gap_v,
            flags: (adc_clipped as u32) | ((dac_clipped as u32) << 2),
            ..Default::default()
        }
    }
}

/// A minimal PI position controller (what `--demo` runs in a thread): holds 1 µm.
fn demo_controller(prefix: &str) -> (f64, u64) {
    let ep = Endpoint::open(prefix, "controller").expect("join the run");
    let mut daq = ControllerLink::new(&ep, Duration::from_secs(10), Duration::from_secs(1))
        .expect("controller ports");
    let (kp, ki) = (0.02, 0.002);
    let (mut integral, mut last_gap_v, mut ticks) = (0.0, 0.0, 0);
    loop {
        let s = daq.read().expect("sample");
        if s.flags & flags::END != 0 {
            return (last_gap_v / FakeHardware::SENSOR_V_PER_M, ticks);
        }
        let error_v = 1.0 - s.gap_v; // 1 µm at 1 V/µm
        integral += ki * error_v;
        last_gap_v = s.gap_v;
        ticks += 1;
        daq.write(Command {
            seq: s.seq,
            dac_v: kp * error_v + integral,
            ..Default::default()
        })
        .expect("command");
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let value = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let prefix = value("--prefix").unwrap_or_else(|| "lab".into());
    let seconds: f64 = value("--seconds").map_or(1.0, |s| s.parse().expect("--seconds"));
    let realtime = args.iter().any(|a| a == "--realtime");
    let demo = args.iter().any(|a| a == "--demo");
    let own_clock = value("--clock").is_some_and(|c| c == "adc");
    let practice: Option<u64> =
        value("--practice-seed").map(|s| s.parse().expect("--practice-seed"));
    let reveal = value("--reveal");

    let ep = Endpoint::open(&prefix, "plant").expect("join the run");
    let pacing = if realtime || own_clock {
        Pacing::RealTime
    } else {
        Pacing::Lockstep
    };
    let mut opts = ServeOptions::new((seconds * RATE_HZ) as u64, 1.0 / RATE_HZ, pacing);
    // `--wait-recorder`: the first tick waits for `servo record` too (a recording from tick 0).
    opts.wait_for_recorder = args.iter().any(|a| a == "--wait-recorder");
    if demo && pacing == Pacing::RealTime {
        // The demo's controller is a thread of this process on a machine that may be shared:
        // a loss timeout above the ~1 ms stalls of a VM (what `servo latency` recommends).
        opts.peer_timeout = Duration::from_millis(5);
    }
    let controller = demo.then(|| {
        let p = prefix.clone();
        std::thread::spawn(move || demo_controller(&p))
    });
    println!(
        "daq daemon: serving {} on fts-servo/{prefix}/… at {RATE_HZ} Hz ({:?}, {} clock){}",
        if practice.is_some() {
            "a practice stage (hidden parameters)"
        } else {
            "fake hardware"
        },
        pacing,
        if own_clock { "the ADC's" } else { "the wall" },
        if demo {
            ""
        } else {
            "; start a controller with the same --prefix"
        }
    );
    let stop = AtomicUsize::new(0);
    let report = match practice {
        Some(seed) => {
            let mut stage = PracticeStage::new(&PlantParams::default(), seed, Default::default())
                .unwrap_or_else(|e| panic!("daq daemon: practice stage: {e}"));
            let report = serve(&ep, &mut stage, &opts, &stop);
            if let Some(path) = &reveal {
                // A new file only: the draw is never written over something else.
                let mut file = std::fs::OpenOptions::new()
                    .write(true)
                    .create_new(true)
                    .open(path)
                    .unwrap_or_else(|e| panic!("daq daemon: --reveal {path}: {e}"));
                let text = toml::to_string(stage.draw()).expect("the draw serialises");
                std::io::Write::write_all(&mut file, text.as_bytes())
                    .unwrap_or_else(|e| panic!("daq daemon: --reveal {path}: {e}"));
            }
            report
        }
        None => serve(&ep, &mut FakeHardware::new(own_clock), &opts, &stop),
    }
    .unwrap_or_else(|e| panic!("daq daemon: {e}"));
    let (l, late) = (report.latency, report.lateness);
    println!(
        "  {} ticks in {:.3} s, {} overruns, faults {:#x}; round trip median {:.2} µs, p99.9 {:.2} µs; start lateness median {:.2} µs, max {:.1} µs",
        report.ticks,
        report.wall_s,
        report.overruns,
        report.faults,
        l.p50_ns as f64 * 1e-3,
        l.p999_ns as f64 * 1e-3,
        late.p50_ns as f64 * 1e-3,
        late.max_ns as f64 * 1e-3
    );
    if let Some(c) = controller {
        let (x_m, ticks) = c.join().expect("demo controller");
        println!(
            "  demo controller: {ticks} ticks, stage at {:.4} µm (set point 1 µm)",
            x_m * 1e6
        );
        assert!(
            (x_m - 1e-6).abs() < 1e-9,
            "the demo loop holds 1 µm within 1 nm"
        );
    }
}
