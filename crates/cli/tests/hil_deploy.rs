//! Deploying while running (issue 17): `servo ctl load` swaps the controller of a running HIL
//! loop at a tick boundary, bumplessly, after checking the new loop on the run's model; a
//! controller made for another stage or one that would be unstable is refused with the
//! reason and the running one stays; the recording notes the swap's tick and file hash.

use crate::common;

use common::hil::{
    assert_bumpless, assert_swapped_in, ctl_load, ctl_stop, long_hil_run, prefix,
    recorded_commands, swap_tick, wait_for_ticks,
};
use common::{servo, tmp, tuned};

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
    let mut run = long_hil_run(&p, &rec, |cmd| {
        cmd.args(rate).args([
            "--scenario",
            "sine",
            "--amplitude",
            "1e-6",
            "--frequency",
            "100",
        ]);
    });
    let refused = |file: &std::path::Path, why: &[&str]| {
        let out = ctl_load(&p, file);
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{e}");
        for w in why {
            assert!(e.contains(w), "{e}");
        }
    };
    refused(&unstable, &["would be unstable", "spectral radius"]);
    refused(&heavy, &["made for another plant", "stage heavy"]);
    // A load swaps the feedback controller; a feedforward change would be ignored: refused.
    let with_feedforward = tmp("deploy-feedforward.toml");
    let gains = std::fs::read_to_string(&pid).unwrap();
    std::fs::write(
        &with_feedforward,
        format!("[controller]\nfeedforward = \"model\"\n{gains}"),
    )
    .unwrap();
    refused(&with_feedforward, &["change of feedforward"]);
    let swap = swap_tick(&ctl_load(&p, &pid));
    wait_for_ticks(&p, swap as u64 + 20_000, &mut run);
    ctl_stop(&p);
    let summary = run.wait_with_output().unwrap();
    let s: serde_json::Value = serde_json::from_slice(&summary.stdout).unwrap();
    assert!(s["trip"].is_null(), "{s}");

    let (u, end) = recorded_commands(&rec);
    assert_bumpless(&u, swap);
    // Recorded: the tick and the file's SHA-256, and the file itself.
    assert_swapped_in(&rec, swap, &pid);
    // A replay runs the recorded controller: bit for bit up to the swap, not compared after.
    let replay = common::json(
        &servo()
            .args(["replay", "--json", "--no-record"])
            .arg(&rec)
            .output()
            .unwrap(),
    );
    assert_eq!(
        replay["compared_until_operator_tick"], swap as u64,
        "{replay}"
    );
    assert_eq!(replay["frames_compared"], swap as u64, "{replay}");
    assert_eq!(replay["identical"], true, "{replay}");
    let noted = &end["controller_load.1"];
    let sha = run_config::sha256_hex(&std::fs::read(&pid).unwrap());
    assert!(
        noted.starts_with(&format!("tick {swap}:")) && noted.contains(&sha),
        "{noted}"
    );
}
