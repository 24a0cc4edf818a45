//! HIL control: `servo ctl` acknowledged and checked against the loop's margins, a live
//! prefix refused to a second run, machine protection across processes.

use crate::common;

use common::hil::{long_hil_run, prefix, wait_for_ticks};
use common::{as_nobody, euid, json, servo, succeeded, tmp};
use std::process::Stdio;

/// The control plane: `servo ctl gain` scales the controller output from the next health
/// boundary on (states identical until then, so the first changed command is exactly 1.5×
/// the unscaled one); `servo ctl stop` ends the run early with a finished recording.
#[test]
fn control_plane_changes_gains_and_stops_a_running_loop() {
    let (a, b) = (tmp("ctl-ref.mcap"), tmp("ctl.mcap"));
    let common = [
        "--duration",
        "20",
        "--scenario",
        "sine",
        "--amplitude",
        "1e-6",
        "--frequency",
        "100",
        "-q",
    ];
    let p = prefix("ctl");
    let mut run = servo()
        .args(["run", "--hil", "--json", "--prefix", &p, "--out"])
        .arg(&b)
        .args(common)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_ticks(&p, 20_000, &mut run);
    let ctl = |args: &[&str]| {
        servo()
            .args(["ctl", "--prefix", &p, "--timeout-s", "60"])
            .args(args)
            .output()
            .unwrap()
    };
    // Beyond the margin: the default PID goes unstable at ×4.41 (12.9 dB, the issue's
    // number; studies' `gain_margin_predicts_the_stability_limit` checks the limit itself).
    for (scale, why) in [
        ("4", "refused: the loop goes unstable above ×4.409"),
        ("nan", "not a finite number"),
    ] {
        let out = ctl(&["gain", scale]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(why), "{err}");
        if scale == "4" {
            assert!(
                err.contains("12.9 dB") && err.contains("allowed ×0.041–×2.205"),
                "{err}"
            );
        }
    }
    let out = ctl(&["gain", "1.5"]);
    succeeded(&out);
    let said = String::from_utf8_lossy(&out.stdout).to_string();
    let applied: u64 = said
        .split("applied from tick ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{said}"));
    wait_for_ticks(&p, 60_000, &mut run);
    let out = ctl(&["stop"]);
    succeeded(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("stop applied: the run ends at tick"));
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success());
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["meta"]["interrupted"], true);
    assert_eq!(
        summary["meta"]["end_reason"], "stopped",
        "by servo ctl stop"
    );
    let changed = recorder::read(&b).unwrap().frames;
    assert!(changed.len() < 20 * 199_600 && changed.len() >= 60_000);
    // The same run, in process, without the change, as long as the changed one.
    let secs = format!("{}", changed.len() as f64 / 199_600.0 + 1e-3);
    let mut args = common.to_vec();
    args[1] = &secs;
    json(
        &servo()
            .args([&["run", "--json", "--out", a.to_str().unwrap()][..], &args].concat())
            .output()
            .unwrap(),
    );
    let reference = recorder::read(&a).unwrap().frames;
    let j = changed
        .iter()
        .zip(&reference)
        .position(|(x, y)| x != y)
        .expect("the gain change shows");
    assert!(
        j >= 20_000,
        "changed at tick {j}, before the command was sent"
    );
    let ratio = changed[j].telemetry.control_v / reference[j].telemetry.control_v;
    assert!(
        (ratio - 1.5).abs() < 1e-5,
        "first scaled command ratio {ratio}"
    );
    // The acknowledgement named that tick, and the recording holds the change (only the
    // accepted one).
    assert_eq!(applied, j as u64);
    let end = recorder::read(&b).unwrap().end;
    assert_eq!(end["gain_change.1"], format!("tick {j}: output scale 1.5"));
    assert!(!end.contains_key("gain_change.2"));
    let log = runner::operator_log::OperatorLog::read(&b).unwrap();
    assert_eq!(log.gain_changes.len(), 1);
    assert_eq!(
        (log.gain_changes[0].tick, log.gain_changes[0].scale),
        (j as u64, 1.5)
    );
    // A replay runs the configuration alone: bit for bit up to the change, not after.
    let replay = json(
        &servo()
            .args(["replay", "--json", "--no-record"])
            .arg(&b)
            .output()
            .unwrap(),
    );
    assert_eq!(replay["compared_until_operator_tick"], j as u64, "{replay}");
    assert_eq!(replay["frames_compared"], j as u64, "{replay}");
    assert_eq!(replay["identical"], true, "{replay}");
}

/// `servo ctl` to a prefix no run holds fails at once (not after its 60 s timeout) and says so.
#[test]
fn ctl_to_a_prefix_without_a_run_fails_fast() {
    for action in [&["gain", "1.2"][..], &["stop"], &["start"]] {
        let out = servo()
            .args(["ctl", "--prefix", &prefix("nobody"), "--timeout-s", "60"])
            .args(action)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains("no run on prefix"), "{err}");
    }
}

/// A second run on a prefix a live run holds is refused before it makes anything, naming the
/// live run; the first run's recording is untouched (its own seed, complete).
#[test]
fn a_second_run_on_a_live_prefix_is_refused() {
    let p = prefix("twice");
    let (first, second) = (tmp("twice-1.mcap"), tmp("twice-2.mcap"));
    let run = long_hil_run(&p, &first, |c| {
        c.args(["--seed", "1"]);
    });
    let pid = run.id();
    for args in [
        &[
            "run",
            "--hil",
            "--seed",
            "2",
            "--duration",
            "1",
            "--prefix",
            &p,
            "--out",
            second.to_str().unwrap(),
        ][..],
        &[
            "record",
            "--seed",
            "2",
            "--duration",
            "1",
            "--prefix",
            &p,
            "--out",
            second.to_str().unwrap(),
        ],
        &["plant", "--prefix", &p],
        &["controller", "--prefix", &p],
    ] {
        let out = servo().args(args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("is in use by a live run") && err.contains("started"),
            "{err}"
        );
        if args[0] == "run" {
            assert!(err.contains(&format!("pid {pid}")), "{err}");
        }
        assert!(!second.exists(), "{args:?} made its recording");
    }
    succeeded(
        &servo()
            .args(["ctl", "--prefix", &p, "--timeout-s", "60", "stop"])
            .output()
            .unwrap(),
    );
    let out = run.wait_with_output().unwrap();
    succeeded(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["meta"]["seed"], 1);
    let rec = recorder::read(&first).unwrap();
    assert_eq!(
        rec.report.as_ref().unwrap().state,
        recorder::FileState::Finished
    );
    assert_eq!(Some(rec.frames.len() as u64), summary["ticks"].as_u64());
    assert_eq!(rec.end["reason"], "stopped");
}

/// The 40 µm step (beyond the ±25.6 µm sensor) trips the loop in process and in
/// lockstep HIL at the same tick: exit 5, the recording's `end` record says `tripped` with the
/// cause and tick, and the frames agree up to the in-process end (the HIL plant ends at its
/// next control-plane check after the controller's STOP, still in the safe state).
#[test]
fn a_trip_ends_the_run_with_exit_5_in_process_and_in_hil() {
    let (a, b) = (tmp("trip-inproc.mcap"), tmp("trip-hil.mcap"));
    let common = [
        "--scenario",
        "step",
        "--amplitude",
        "40e-6",
        "--duration",
        "0.1",
        "-q",
        "--json",
    ];
    let p = prefix("trip");
    let runs = [
        [&["run", "--out", a.to_str().unwrap()][..], &common].concat(),
        [
            &["run", "--hil", "--prefix", &p, "--out", b.to_str().unwrap()][..],
            &common,
        ]
        .concat(),
    ];
    let mut ends = Vec::new();
    for (args, path) in runs.iter().zip([&a, &b]) {
        let out = servo().args(args).output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(5),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        // Seen once in CI (not reproduced in 10 local runs, with or without load): exit 5
        // with no summary on stdout; show what the processes said if it happens again.
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
            panic!(
                "{args:?}: no summary ({e}); stderr: {}",
                String::from_utf8_lossy(&out.stderr)
            )
        });
        assert_eq!(v["trip"]["cause"], "following-error", "{args:?}");
        assert_eq!(v["meta"]["end_reason"], "tripped");
        let rec = recorder::read(path).unwrap();
        assert_eq!(
            rec.report.as_ref().unwrap().state,
            recorder::FileState::Finished
        );
        assert_eq!(rec.end["reason"], "tripped");
        assert_eq!(rec.end["safe_state"], "zero");
        assert_eq!(rec.end["trip_tick"], v["trip"]["tick"].to_string());
        ends.push((rec, v));
    }
    let ((inproc, v), (hil, w)) = (&ends[0], &ends[1]);
    assert_eq!(v["trip"], w["trip"]);
    // The step is at 20 % of 0.1 s = tick 3992; the trip follows it within two ticks.
    let tick = v["trip"]["tick"].as_u64().unwrap();
    assert!((3992..=3994).contains(&tick), "{tick}");
    let n = inproc.frames.len();
    assert_eq!(n as u64, tick + 998 + 1);
    assert!(hil.frames.len() >= n && hil.frames.len() <= n + 2048);
    assert_eq!(inproc.frames[..], hil.frames[..n]);
    assert!(hil.frames[n..].iter().all(|f| f.telemetry.control_v == 0.0));
}

/// Another user on the machine (`nobody`, acting from root's tests; CI runs it as root with
/// `-- --ignored _as_root`): a folder pre-created at the old predictable path (a hostile
/// `kp = 16.5` and a symlink to a system file) is neither read nor written by the run; the
/// run's own config folder is mode 0700 and unreadable to them; `servo ctl` from them changes
/// nothing; the run records its own configuration and only root's commands.
#[test]
#[ignore = "needs root (acts as another user): CI runs it, `-- --ignored _as_root`"]
fn another_user_can_neither_read_the_config_nor_steer_the_run_as_root() {
    assert_eq!(euid(), 0, "acting as another user needs root");
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let shared = tmp("shared-tmp");
    std::fs::create_dir_all(&shared).unwrap();
    std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o1777)).unwrap();
    std::fs::set_permissions(
        shared.parent().unwrap(),
        std::fs::Permissions::from_mode(0o755),
    )
    .unwrap();
    let p = prefix("users");
    let planted = shared.join(format!("fts-servo-{p}"));
    let plant_files = format!(
        "mkdir -p '{d}' && printf '[controller.pid]\\nkp = 16.5\\n' > '{d}/config.toml' && ln -s /etc/passwd '{d}/link'",
        d = planted.display()
    );
    let mut sh = std::process::Command::new("sh");
    sh.args(["-c", &plant_files]);
    assert!(as_nobody(sh).status.success(), "nobody plants the folder");
    let out = tmp("users.mcap");
    let run = long_hil_run(&p, &out, |c| {
        c.env("TMPDIR", &shared);
    });
    // The run's own folder: one, root's, 0700, unreadable to nobody.
    let own: Vec<_> = std::fs::read_dir(&shared)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|d| {
            d != &planted
                && d.file_name()
                    .unwrap()
                    .to_string_lossy()
                    .starts_with("fts-servo-")
        })
        .collect();
    assert_eq!(own.len(), 1, "{own:?}");
    let meta = std::fs::metadata(&own[0]).unwrap();
    assert_eq!((meta.mode() & 0o777, meta.uid()), (0o700, 0));
    let mut cat = std::process::Command::new("cat");
    cat.arg(own[0].join("config.toml"));
    assert!(
        !as_nobody(cat).status.success(),
        "nobody read the run's config"
    );
    // Nobody's commands do not reach the loop.
    for action in [&["gain", "1.5"][..], &["stop"]] {
        let mut ctl = servo();
        ctl.args(["ctl", "--prefix", &p, "--timeout-s", "2"])
            .args(action);
        let o = as_nobody(ctl);
        assert!(!o.status.success(), "nobody's ctl {action:?} was accepted");
    }
    succeeded(
        &servo()
            .args(["ctl", "--prefix", &p, "--timeout-s", "60", "stop"])
            .output()
            .unwrap(),
    );
    let done = run.wait_with_output().unwrap();
    succeeded(&done);
    let rec = recorder::read(&out).unwrap();
    assert!(
        rec.metadata["config"].contains("kp = 1.65"),
        "the run's own gains"
    );
    assert_eq!(rec.end["reason"], "stopped");
    assert!(!rec.end.keys().any(|k| k.starts_with("gain_change")));
    // The planted files are as nobody left them; the run's folder is gone.
    let planted_config = std::fs::read_to_string(planted.join("config.toml")).unwrap();
    assert_eq!(planted_config, "[controller.pid]\nkp = 16.5\n");
    assert!(std::fs::symlink_metadata(planted.join("link"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(!own[0].exists());
    let _ = std::fs::remove_dir_all(&planted);
}
