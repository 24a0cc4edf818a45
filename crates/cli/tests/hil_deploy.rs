//! Deploying while running (issue 17): `servo ctl load` swaps the controller of a running HIL
//! loop at a tick boundary, bumplessly, after checking the new loop on the run's model; a
//! controller made for another stage or one that would be unstable is refused with the
//! reason and the running one stays; the recording notes the swap's tick and file hash.

mod common;

use common::hil::{prefix, wait_for_ticks};
use common::{servo, succeeded, tmp, tuned};
use recorder::Frame;
use runner::recording::FrameSink;
use std::process::Stdio;

/// Every recorded command, V, in tick order.
#[derive(Default)]
struct Commands(Vec<f64>);

impl FrameSink for Commands {
    fn frame(&mut self, f: &Frame) {
        self.0.push(f64::from(f.telemetry.control_v));
    }
}

#[test]
fn a_controller_loaded_into_the_running_loop_takes_over_bumplessly() {
    let rate = ["--rate", "20000"];
    let pid = tuned(
        "deploy-pid.toml",
        &["--rate", "20000", "--bandwidth-hz", "1000"],
    );
    let heavy = tuned("deploy-heavy.toml", &["--rate", "20000", "--mass", "heavy"]);
    let unstable = tmp("deploy-unstable.toml");
    std::fs::write(
        &unstable,
        "[controller.pid]\nkp = 40.0\nki = 0.0\nkd = 0.0\n",
    )
    .unwrap();

    let p = prefix("deploy");
    let rec = tmp("deploy.mcap");
    let mut run = servo()
        .args([
            "run",
            "--hil",
            "-q",
            "--json",
            "--duration",
            "300",
            "--prefix",
            &p,
        ])
        .args(rate)
        .args([
            "--scenario",
            "sine",
            "--amplitude",
            "1e-6",
            "--frequency",
            "100",
        ])
        .arg("--out")
        .arg(&rec)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_ticks(&p, 20_000, &mut run);
    let load = |file: &std::path::Path| {
        servo()
            .args(["ctl", "--prefix", &p, "--timeout-s", "60", "load"])
            .arg(file)
            .output()
            .unwrap()
    };
    let refused = |file: &std::path::Path, why: &[&str]| {
        let out = load(file);
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{e}");
        for w in why {
            assert!(e.contains(w), "{e}");
        }
    };
    refused(&unstable, &["would be unstable", "spectral radius"]);
    refused(&heavy, &["made for another plant", "stage heavy"]);
    let out = load(&pid);
    succeeded(&out);
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    let swap: usize = said
        .split("took the loop at tick ")
        .nth(1)
        .and_then(|r| r.split(',').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    wait_for_ticks(&p, swap as u64 + 20_000, &mut run);
    succeeded(
        &servo()
            .args(["ctl", "--prefix", &p, "--timeout-s", "60", "stop"])
            .output()
            .unwrap(),
    );
    let summary = run.wait_with_output().unwrap();
    let s: serde_json::Value = serde_json::from_slice(&summary.stdout).unwrap();
    assert!(s["trip"].is_null(), "{s}");

    let mut u = Commands::default();
    let read = runner::recording::inspect_with(&rec, &mut u).unwrap();
    let u = u.0;
    assert!(u.len() > swap + 10_000, "{} frames", u.len());
    // Bumpless: the command step at the swap tick is an ordinary one — no larger than the
    // 99.9th percentile of the tick-to-tick changes over the 10 000 ticks before.
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
    // Recorded: the tick and the file's SHA-256.
    let noted = &read.end["controller_load.1"];
    let sha = runner::config::sha256_hex(&std::fs::read(&pid).unwrap());
    assert!(
        noted.starts_with(&format!("tick {swap}:")) && noted.contains(&sha),
        "{noted}"
    );
}
