//! `servo replay` (issue 17): a recording re-run from what it holds reproduces its data
//! channels bit for bit; with a replaced controller it is the run that controller would have
//! made (the same as running it directly); a recording without simulator truth replays only
//! on an identified model.

use crate::common;

use common::{json, servo, succeeded, tmp, tuned};
use std::path::Path;

fn record(file: &Path, extra: &[&str]) {
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "0.5", "--seed", "7", "--out"])
            .arg(file)
            .args(extra)
            .output()
            .unwrap(),
    );
}

fn replay(file: &Path, extra: &[&str]) -> serde_json::Value {
    json(
        &servo()
            .arg("replay")
            .arg(file)
            .args(["--no-record", "--json", "-q"])
            .args(extra)
            .output()
            .unwrap(),
    )
}

#[test]
fn an_unchanged_replay_reproduces_the_recording_bit_for_bit() {
    let file = tmp("as-recorded.mcap");
    record(
        &file,
        &[
            "--mass",
            "heavy",
            "--scenario",
            "sine",
            "--amplitude",
            "1e-6",
        ],
    );
    let r = replay(&file, &[]);
    assert_eq!(r["changed"], false);
    assert_eq!(r["identical"], true, "{r}");
    assert_eq!(r["frames_compared"], 99_800);
    assert_eq!(
        r["recorded"]["following_error_m"],
        r["replayed"]["following_error_m"]
    );
    // Recorded again, the replay's own file is another identical recording.
    let again = tmp("as-recorded.replay.mcap");
    succeeded(
        &servo()
            .arg("replay")
            .arg(&file)
            .args(["-q", "--out"])
            .arg(&again)
            .output()
            .unwrap(),
    );
    assert_eq!(replay(&again, &[])["identical"], true);
}

#[test]
fn a_replay_with_another_controller_is_the_run_that_controller_makes() {
    let file = tmp("pid-original.mcap");
    record(&file, &[]);
    let pid = tuned("pid-1500.toml", &["--bandwidth-hz", "1500"]);
    let r = replay(&file, &["--controller-from", pid.to_str().unwrap()]);
    assert_eq!(r["changed"], true);
    assert_eq!(r["identical"], false);
    let direct = json(
        &servo()
            .args([
                "run",
                "--no-record",
                "--json",
                "-q",
                "--duration",
                "0.5",
                "--seed",
                "7",
                "-c",
            ])
            .arg(&pid)
            .output()
            .unwrap(),
    );
    for key in ["following_error_m", "true_error_m", "control_v"] {
        assert_eq!(r["replayed"][key], direct[key], "{key}");
        assert_ne!(r["replayed"][key], r["recorded"][key], "{key}");
    }
    // Made for another stage: refused with both named, as a run refuses it.
    let heavy = tuned("pid-heavy.toml", &["--mass", "heavy"]);
    let out = servo()
        .arg("replay")
        .arg(&file)
        .args(["--no-record", "-q", "--controller-from"])
        .arg(&heavy)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains("stage heavy") && e.contains("stage light"),
        "{e}"
    );
}

/// A recording whose frames carry no truth (as a DAQ daemon's): refused on the simulator's
/// stage, replayed on a plant file.
#[test]
fn a_recording_without_truth_replays_only_on_an_identified_model() {
    let file = tmp("no-truth.mcap");
    let plan = runner::Plan::new(&run_config::Loaded::default()).unwrap();
    let plan = plan.with_duration(0.01).unwrap();
    let mut rec =
        runner::recording::create(&plan, &runner::recording::Target::new(&file), 1).unwrap();
    let ticks = plan.config.ticks();
    for k in 0..ticks {
        let t = daq_io::Telemetry {
            seq: k,
            time_s: k as f64 * plan.period_s(),
            following_error_m: 1e-9,
            ..Default::default()
        };
        rec.push(recorder::Frame::join(&t, &daq_io::Truth::default()))
            .unwrap();
    }
    let mut end = std::collections::BTreeMap::new();
    end.insert("reason".to_string(), "completed".to_string());
    rec.finish(end).unwrap();
    let out = servo()
        .arg("replay")
        .arg(&file)
        .args(["--no-record", "-q"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("no-truth.mcap") && e.contains("--plant"), "{e}");
    let model = tmp("no-truth-model.toml");
    std::fs::write(&model, run_config::plant_toml(&plan.config.plant)).unwrap();
    let r = replay(&file, &["--plant", model.to_str().unwrap()]);
    assert_eq!(r["identical"], false);
    assert!(r["replayed"]["true_error_m"]["rms"].as_f64().unwrap() > 0.0);
}
