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
