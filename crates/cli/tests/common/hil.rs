//! What the HIL tests share: a run prefix of their own, waiting for a run to make progress.
#![allow(dead_code)] // each test file uses a part

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

/// A run prefix unique to this test process and `tag`.
pub fn prefix(tag: &str) -> String {
    format!("t-{tag}-{}", std::process::id())
}

/// Waits until the plant of run `prefix` reports `ticks` done on the health service of the
/// control plane; fails if `run` (the process that drives the run) exits first. No clock: a
/// slow machine only waits longer.
pub fn wait_for_ticks(prefix: &str, ticks: u64, run: &mut Child) {
    let ep = daq_io::ipc::Endpoint::open(prefix, "test-watch").unwrap();
    let health = ep
        .subscriber::<daq_io::Health>(daq_io::ipc::leaf::HEALTH)
        .unwrap();
    loop {
        while let Some(h) = daq_io::ipc::take(&health) {
            if h.role == daq_io::contract::role::PLANT && h.ticks >= ticks {
                return;
            }
        }
        if let Some(status) = run.try_wait().unwrap() {
            panic!("the run ended ({status}) before tick {ticks}");
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A 60 s `servo run --hil` on prefix `p` recording to `out` (JSON summary on a piped stdout),
/// as `customise` adjusts it (more flags, environment, stderr), started and 20 000 ticks in.
pub fn long_hil_run(p: &str, out: &Path, customise: impl FnOnce(&mut Command)) -> Child {
    let mut cmd = super::servo();
    cmd.args([
        "run",
        "--hil",
        "-q",
        "--json",
        "--duration",
        "60",
        "--prefix",
        p,
        "--out",
    ])
    .arg(out)
    .stdout(Stdio::piped());
    customise(&mut cmd);
    let mut run = cmd.spawn().unwrap();
    wait_for_ticks(p, 20_000, &mut run);
    run
}

/// Every recorded command of `file`, V, in tick order, and the recording's end record.
pub fn recorded_commands(file: &Path) -> (Vec<f64>, std::collections::BTreeMap<String, String>) {
    struct Commands(Vec<f64>);
    impl runner::recording::FrameSink for Commands {
        fn frame(&mut self, f: &recorder::Frame) {
            self.0.push(f64::from(f.telemetry.control_v));
        }
    }
    let mut u = Commands(Vec::new());
    let read = runner::recording::inspect_with(file, &mut u).unwrap();
    (u.0, read.end)
}

/// Bumpless: the command step at tick `swap` is an ordinary one — no larger than the 99.9th
/// percentile of the tick-to-tick changes of `u` over the 10 000 ticks before.
pub fn assert_bumpless(u: &[f64], swap: usize) {
    assert!(u.len() > swap + 10_000, "{} frames", u.len());
    let mut steps: Vec<f64> = (swap - 10_000..swap)
        .map(|k| (u[k] - u[k - 1]).abs())
        .collect();
    steps.sort_by(f64::total_cmp);
    let p999 = steps[steps.len() * 999 / 1000];
    let at_swap = (u[swap] - u[swap - 1]).abs();
    assert!(
        at_swap <= p999,
        "step {at_swap} V at the swap vs p99.9 {p999} V"
    );
}

/// `servo ctl load file` on run `prefix`: its output.
pub fn ctl_load(prefix: &str, file: &Path) -> std::process::Output {
    super::servo()
        .args(["ctl", "--prefix", prefix, "--timeout-s", "60", "load"])
        .arg(file)
        .output()
        .unwrap()
}

/// The tick at which a successful `servo ctl load` says the loaded controller took the loop.
pub fn swap_tick(load: &std::process::Output) -> usize {
    super::succeeded(load);
    let said = String::from_utf8_lossy(&load.stdout);
    said.split("took the loop at tick ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{said}"))
}

/// `servo ctl stop` on run `prefix`, acknowledged.
pub fn ctl_stop(prefix: &str) {
    super::succeeded(
        &super::servo()
            .args(["ctl", "--prefix", prefix, "--timeout-s", "60", "stop"])
            .output()
            .unwrap(),
    );
}

/// The recording `rec` holds one controller swap: `file`, at tick `swap`.
pub fn assert_swapped_in(rec: &Path, swap: usize, file: &Path) {
    let swaps = runner::operator_log::OperatorLog::read(rec).unwrap().swaps;
    assert_eq!(swaps.len(), 1);
    assert_eq!(
        (swaps[0].tick, &swaps[0].file),
        (swap as u64, &std::fs::read(file).unwrap())
    );
}
