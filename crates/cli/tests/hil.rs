//! HIL: plant, controller and recorder as separate processes over iceoryx2, as a user runs
//! them. Each test uses its own run prefix (with the test process id) so tests run in parallel.

use crate::common;

use common::hil::{long_hil_run, prefix, wait_for_ticks};
use common::{json, servo, tmp};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

fn run_ok(args: &[&str]) -> serde_json::Value {
    json(&servo().args(args).output().unwrap())
}

/// In-process and lockstep HIL recordings of the same config: frame by frame identical.
fn assert_same_recording(a: &Path, b: &Path) {
    let (a, b) = (recorder::read(a).unwrap(), recorder::read(b).unwrap());
    assert_eq!(a.frames.len(), b.frames.len());
    let first_diff = a.frames.iter().zip(&b.frames).position(|(x, y)| x != y);
    assert_eq!(first_diff, None, "frames differ");
}

/// `servo run --hil` (lockstep) of `common` records what `servo run` records, frame for frame.
fn hil_equals_in_process(tag: &str, common: &[&str], seconds: f64) {
    let (a, b) = (
        tmp(&format!("{tag}-inproc.mcap")),
        tmp(&format!("{tag}-hil.mcap")),
    );
    let inproc = run_ok(&[&["run", "--out", a.to_str().unwrap()][..], common].concat());
    let p = prefix(tag);
    let hil = run_ok(
        &[
            &["run", "--hil", "--prefix", &p, "--out", b.to_str().unwrap()][..],
            common,
        ]
        .concat(),
    );
    assert_same_recording(&a, &b);
    for key in ["following_error_m", "true_error_m", "control_v"] {
        assert_eq!(inproc[key], hil[key], "{key}");
    }
    assert_eq!(hil["meta"]["dropped_frames"], 0);
    assert_eq!(hil["meta"]["hil"]["faults"], 0);
    let ticks = (seconds * 199_600.0).round() as u64;
    assert_eq!(hil["ticks"], ticks);
    // Every timed tick (all but the start-up exchange) in the plant's and the controller's
    // statistics, percentiles in order; lockstep has no deadlines, so no lateness.
    let h = &hil["meta"]["hil"];
    for key in [
        "plant_execution",
        "controller_execution",
        "controller_lateness",
    ] {
        let l = &h[key];
        assert_eq!(l["count"], ticks - 1, "{key}: {l}");
        let q: Vec<u64> = [
            "min_ns", "p50_ns", "p99_ns", "p999_ns", "p9999_ns", "max_ns",
        ]
        .iter()
        .map(|k| l[k].as_u64().unwrap())
        .collect();
        assert!(
            q.windows(2).all(|w| w[0] <= w[1]) && q[1] > 0,
            "{key}: {q:?}"
        );
    }
    assert_eq!(h["plant_lateness"]["count"], 0);
    // The recording's end record keeps them.
    let bytes = std::fs::read(&b).unwrap();
    let text = String::from_utf8_lossy(&bytes);
    for key in [
        "hil.plant.execution",
        "hil.controller.execution",
        "hil.round_trip",
    ] {
        assert!(text.contains(key), "{key} in the end record");
    }
}

#[test]
fn lockstep_hil_equals_the_in_process_run_bit_for_bit() {
    let common = [
        "--duration",
        "0.3",
        "--scenario",
        "sine",
        "--seed",
        "5",
        "-q",
        "--json",
    ];
    hil_equals_in_process("bits", &common, 0.3);
}

/// Machining over shared memory: the plant's encoder count crosses the process boundary and
/// the controller's tracker, surface and ZPETC compute the same commands.
#[test]
fn lockstep_hil_machining_with_zpetc_equals_the_in_process_run() {
    let common = [
        "--duration",
        "0.2",
        "--scenario",
        "machine",
        "--feedforward",
        "zpetc",
        "-q",
        "--json",
    ];
    hil_equals_in_process("machine", &common, 0.2);
}

#[test]
fn two_concurrent_runs_with_different_prefixes_do_not_interfere() {
    let runs: Vec<(PathBuf, PathBuf, Child)> = [("a", "1", "heavy"), ("b", "2", "light")]
        .iter()
        .map(|(tag, seed, mass)| {
            let (solo, hil) = (
                tmp(&format!("solo-{tag}.mcap")),
                tmp(&format!("par-{tag}.mcap")),
            );
            let common = [
                "--duration",
                "0.2",
                "--seed",
                seed,
                "--mass",
                mass,
                "-q",
                "--json",
            ];
            run_ok(&[&["run", "--out", solo.to_str().unwrap()][..], &common].concat());
            let child = servo()
                .args(["run", "--hil", "--prefix", &prefix(tag), "--out"])
                .arg(&hil)
                .args(common)
                .stdout(Stdio::null())
                .spawn()
                .unwrap();
            (solo, hil, child)
        })
        .collect();
    for (solo, hil, mut child) in runs {
        assert!(child.wait().unwrap().success());
        assert_same_recording(&solo, &hil);
    }
}

fn spawn(args: &[&str]) -> Child {
    servo()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Lockstep: the plant waits 200 ms for each command, so the first unanswered tick is the
/// fault tick and the DAC is at 0 V from it; the current must be gone within 1 ms of
/// simulated time. (Real-time detection is tested in daq-io with a timeout no stall reaches.)
#[test]
fn killing_the_controller_puts_the_coil_current_to_zero_within_1_ms() {
    let p = prefix("kill");
    let out = tmp("kill.mcap");
    // A 200 Hz, 2 µm sine needs real current; noise off so "zero" means zero.
    let cfg = [
        "--duration",
        "20",
        "--scenario",
        "sine",
        "--amplitude",
        "2e-6",
        "--frequency",
        "200",
        "--noise",
        "none",
        "--prefix",
        &p,
    ];
    let mut record = spawn(
        &[
            &["record", "--json", "-q", "--out", out.to_str().unwrap()][..],
            &cfg,
        ]
        .concat(),
    );
    let mut controller = spawn(&[&["controller"][..], &cfg].concat());
    let mut plant = spawn(&[&["plant"][..], &cfg].concat());
    wait_for_ticks(&p, 100_000, &mut plant);
    controller.kill().unwrap(); // SIGKILL
    controller.wait().unwrap();
    let plant = plant.wait_with_output().unwrap();
    assert_eq!(
        plant.status.code(),
        Some(3),
        "plant exit: {}",
        String::from_utf8_lossy(&plant.stderr)
    );
    assert!(String::from_utf8_lossy(&plant.stderr).contains("controller lost"));
    assert!(record.wait().unwrap().success());

    let frames = recorder::read(&out).unwrap().frames;
    let flag = |f: &recorder::Frame, bit: u32| (f.telemetry.flags as u32) & bit != 0;
    let fault = frames
        .iter()
        .position(|f| flag(f, daq_io::flags::FAULT_PEER_LOST))
        .expect("fault flagged in the recording");
    // The last tick with a command: before the run of overruns that ended in the fault.
    let last_command = (0..fault)
        .rev()
        .find(|&k| !flag(&frames[k], daq_io::flags::OVERRUN))
        .unwrap();
    let period: f64 = 1.0 / 199_600.0;
    assert_eq!(
        fault,
        last_command + 1,
        "lockstep: the first unanswered tick is the fault"
    );
    let before: f64 = frames[last_command - 2000..last_command]
        .iter()
        .map(|f| f.truth.coil_current_a.abs() as f64)
        .fold(0.0, f64::max);
    assert!(before > 1e-3, "the sine drives {before} A");
    let within = last_command + (1e-3 / period).ceil() as usize;
    let after = frames[within..]
        .iter()
        .map(|f| f.truth.coil_current_a.abs() as f64)
        .fold(0.0, f64::max);
    assert!(
        after < 1e-3 * before,
        "current {after} A 1 ms after the last command"
    );
    assert!(frames.len() > within + 100, "safe-state ticks recorded");
}

#[test]
fn a_run_after_kill_9_of_every_process_starts_cleanly() {
    let p = prefix("k9");
    let out = tmp("k9.mcap");
    let cfg = ["--duration", "30", "--prefix", &p];
    let mut children = [
        spawn(&[&["record", "-q", "--out", out.to_str().unwrap()][..], &cfg].concat()),
        spawn(&[&["controller"][..], &cfg].concat()),
        spawn(&[&["plant"][..], &cfg].concat()),
    ];
    wait_for_ticks(&p, 50_000, &mut children[2]);
    for c in children.iter_mut() {
        c.kill().unwrap();
        c.wait().unwrap();
    }
    let v = run_ok(&[
        "run",
        "--hil",
        "--prefix",
        &p,
        "--duration",
        "0.2",
        "-q",
        "--json",
        "--no-record",
    ]);
    assert_eq!(v["ticks"], (0.2f64 * 199_600.0).round() as u64);
    assert_eq!(v["meta"]["hil"]["faults"], 0);
    let f = v["following_error_m"]["rms"].as_f64().unwrap();
    assert!(f > 0.3e-9 && f < 1.2e-9, "following error {f}");
}

#[test]
fn killing_the_plant_stops_the_controller_with_a_clear_message() {
    let p = prefix("plantkill");
    let cfg = ["--duration", "30", "--prefix", &p];
    let controller = spawn(&[&["controller"][..], &cfg].concat());
    let mut plant = spawn(&[&["plant", "--no-recorder"][..], &cfg].concat());
    wait_for_ticks(&p, 20_000, &mut plant);
    plant.kill().unwrap();
    plant.wait().unwrap();
    let out = controller.wait_with_output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("plant lost: no sensor sample for tick"),
        "{err}"
    );
}

/// Processes whose command line names run `prefix` (the HIL children carry `--prefix`).
fn processes_of(prefix: &str) -> Vec<u32> {
    std::fs::read_dir("/proc")
        .unwrap()
        .filter_map(|e| e.ok()?.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            std::fs::read(format!("/proc/{pid}/cmdline"))
                .map(|c| String::from_utf8_lossy(&c).contains(prefix))
                .unwrap_or(false)
        })
        .collect()
}

/// The pid of run `prefix`'s `servo ROLE` child.
fn child_of(prefix: &str, role: &str) -> u32 {
    processes_of(prefix)
        .into_iter()
        .find(|pid| {
            let cmdline = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
            cmdline.split(|&b| b == 0).nth(1) == Some(role.as_bytes())
        })
        .unwrap_or_else(|| panic!("no servo {role} in run {prefix}"))
}

/// A long `servo run --hil` (prefix and recording named after `name`) whose `servo ROLE`
/// child is killed with SIGKILL once the recording holds a few chunks: the run's exit code once
/// no process of it is left, its recording's path and the killed child's pid.
fn kill_mid_run(name: &str, role: &str) -> (Option<i32>, PathBuf, u32) {
    let p = prefix(name);
    let out = tmp(&format!("{name}.mcap"));
    let mut parent = long_hil_run(&p, &out, |c| {
        c.stderr(Stdio::null());
    });
    // 2 MB on disk (whole 20 ms chunks of ≈ 4 000 ticks); a slow machine only waits longer.
    let partial = recorder::partial_path_of(&out, child_of(&p, "record"));
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 2 << 20 {
        assert!(
            parent.try_wait().unwrap().is_none(),
            "ended before the kill"
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    let child = child_of(&p, role);
    let killed = Command::new("kill")
        .args(["-KILL", &child.to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let code = parent.wait().unwrap().code();
    assert!(processes_of(&p).is_empty(), "left: {:?}", processes_of(&p));
    (code, out, child)
}

/// A child of `servo run --hil` killed mid-run (SIGKILL: no handler runs) ends the run as the
/// exit-code table says, with no process left: the plant — a lost peer, the recording finished
/// with end reason `peer-lost` at its last tick, exit 3 (it said `stopped`, exit 255); the
/// recorder — the loop stopped (it ran on unrecorded), exit 137, the `.partial` file
/// salvageable.
#[test]
fn a_killed_child_ends_the_hil_run_as_documented() {
    let (code, out, _) = kill_mid_run("killplant", "plant");
    assert_eq!(code, Some(3));
    let rec = recorder::read(&out).expect("a finished recording");
    assert_eq!(rec.end["reason"], "peer-lost");
    let ticks: usize = rec.end["ticks"].parse().unwrap();
    assert!((20_000..60 * 199_600).contains(&ticks), "{ticks}");

    let (code, out, record) = kill_mid_run("killrec", "record");
    assert_eq!(code, Some(137));
    assert!(!out.exists());
    let partial = recorder::partial_path_of(&out, record);
    let salvaged = run_ok(&["inspect", "--salvage", "--json", partial.to_str().unwrap()]);
    assert!(
        salvaged["summary"]["ticks"].as_u64().unwrap() > 0,
        "{salvaged}"
    );
}

/// SIGINT, SIGHUP or SIGTERM sent to the `servo run --hil` parent alone (as a supervisor
/// sends it) is forwarded as itself: the plant stops at a tick boundary, the recorder finishes
/// the file (complete, `end` record: interrupted by that signal), the parent exits 128 + its
/// number (130, 129, 143), and no child outlives it.
#[test]
fn a_signal_to_the_hil_parent_stops_every_process_and_finishes_the_file() {
    for (signal, code) in [("INT", 130), ("HUP", 129), ("TERM", 143)] {
        let p = prefix(&format!("sig{code}"));
        let out = tmp(&format!("sig{code}.mcap"));
        let mut parent = long_hil_run(&p, &out, |c| {
            c.stderr(Stdio::piped());
        });
        let ok = Command::new("kill")
            .args([&format!("-{signal}"), &parent.id().to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
        let status = parent.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{signal}");
        assert!(
            processes_of(&p).is_empty(),
            "children left: {:?}",
            processes_of(&p)
        );
        let rec = recorder::read(&out).expect("a finished recording");
        assert_eq!(rec.report.unwrap().state, recorder::FileState::Finished);
        assert_eq!(rec.end["reason"], "interrupted");
        assert_eq!(rec.end["signal"], format!("SIG{signal}"));
        let ticks: usize = rec.end["ticks"].parse().unwrap();
        assert!((20_000..60 * 199_600).contains(&ticks), "{ticks}");
        assert_eq!(rec.frames.len(), ticks);
    }
}

/// The HIL recorder's disk filling mid-run (a 2 MB file-size limit on the recorder alone; on
/// every process it would stop iceoryx2 from sizing its shared memory; the limit's SIGXFSZ is
/// not ignored by the shell: servo makes it a write error itself): the recorder asks the plant
/// to stop, the plant ends the run safely and with the controller exits 0, the recorder
/// finishes the recording with the part that fit and exits 4 saying so.
#[test]
fn a_full_disk_in_hil_ends_the_run_safely() {
    let p = prefix("full");
    let dir = tmp("hil-full");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("hil.mcap");
    // The plant's final health report says why it stopped.
    let ep = daq_io::ipc::Endpoint::open(&p, "test-watch").unwrap();
    let health = ep
        .subscriber::<daq_io::Health>(daq_io::ipc::leaf::HEALTH)
        .unwrap();
    let start = |args: &[&str]| {
        servo()
            .args(args)
            .args(["--prefix", &p])
            .stdout(Stdio::null())
            .spawn()
            .unwrap()
    };
    let mut plant = start(&["plant", "--duration", "60"]);
    let mut controller = start(&["controller"]);
    let script = format!(
        "ulimit -f 4000; exec '{}' record -q --json --duration 60 --prefix {p} --out '{}'",
        env!("CARGO_BIN_EXE_servo"),
        out.display()
    );
    let rec = Command::new("sh")
        .args(["-c", &script])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Read the reports while the plant lives (its samples go with it).
    let mut last = None;
    let plant_status = loop {
        let exited = plant.try_wait().unwrap();
        while let Some(h) = daq_io::ipc::take(&health) {
            if h.role == daq_io::contract::role::PLANT {
                last = Some(h);
            }
        }
        if let Some(status) = exited {
            break status;
        }
        std::thread::sleep(Duration::from_millis(2));
    };
    assert!(plant_status.success(), "the plant stops safely");
    assert!(controller.wait().unwrap().success());
    let rec = rec.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&rec.stderr);
    assert_eq!(rec.status.code(), Some(4), "{err}");
    assert!(
        err.contains("hil.mcap") && err.contains("finished with the part that fit"),
        "{err}"
    );
    let last = last.expect("the plant's report");
    assert_eq!(last.state, daq_io::contract::state::DONE);
    assert_eq!(last.stop_cause, daq_io::stop_cause::WRITE_FAILED);
    assert!(
        last.ticks < 60 * 199_600,
        "stopped early: {} ticks",
        last.ticks
    );
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(
        left,
        std::slice::from_ref(&out),
        "only the finished recording is left"
    );
    assert!(std::fs::metadata(&out).unwrap().len() <= 4000 * 512);
    let rec = recorder::read(&out).unwrap();
    assert_eq!(rec.report.unwrap().state, recorder::FileState::Finished);
    assert_eq!(rec.end["reason"], "write-failed");
    assert!(
        rec.end["write_failed"].contains("File too large"),
        "{:?}",
        rec.end
    );
    let n = rec.frames.len();
    assert!(n > 0 && n < 60 * 199_600, "{n} frames");
}

/// SIGTERM sent to one process of a HIL run — the plant, the controller or the recorder, as a
/// service manager stopping it would — ends the whole run at a tick boundary: the recording is
/// finished naming SIGTERM, the parent exits 143 and no process outlives it.
#[test]
fn sigterm_to_any_hil_process_ends_the_run_and_finishes_the_file() {
    for role in ["plant", "controller", "record"] {
        let p = prefix(&format!("term-{role}"));
        let out = tmp(&format!("term-{role}.mcap"));
        let _ = std::fs::remove_file(&out);
        let mut parent = long_hil_run(&p, &out, |c| {
            c.stderr(Stdio::piped());
        });
        let child = processes_of(&p)
            .into_iter()
            .find(|pid| {
                std::fs::read(format!("/proc/{pid}/cmdline"))
                    .is_ok_and(|c| c.split(|b| *b == 0).nth(1) == Some(role.as_bytes()))
            })
            .unwrap_or_else(|| panic!("no {role} process"));
        let ok = Command::new("kill")
            .args(["-TERM", &child.to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
        let status = parent.wait().unwrap();
        assert_eq!(status.code(), Some(143), "SIGTERM to the {role}");
        assert!(processes_of(&p).is_empty(), "{role}: children left");
        let rec = recorder::read(&out).expect("a finished recording");
        assert_eq!(rec.report.unwrap().state, recorder::FileState::Finished);
        assert_eq!(rec.end["reason"], "interrupted", "{role}");
        assert_eq!(rec.end["signal"], "SIGTERM", "{role}");
        let ticks: usize = rec.end["ticks"].parse().unwrap();
        assert_eq!(rec.frames.len(), ticks, "{role}");
    }
}

/// A publisher that breaks the contract — a block whose count is above its capacity, a block
/// whose ticks go backwards, a block of another run — among valid ones, into a recorder and a
/// live view that subscribed before it: neither panics, each counts and names the refused
/// blocks, and the recording holds every valid tick, joined.
#[test]
fn impossible_blocks_are_refused_by_the_recorder_and_the_view() {
    use daq_io::contract::RecordBlock;
    use daq_io::ipc::{leaf, send, subscriber_count, Endpoint};
    use daq_io::{flags, Telemetry, TelemetryBlock, Truth, TruthBlock};
    let p = prefix("badblocks");
    let out = tmp("badblocks.mcap");
    let _ = std::fs::remove_file(&out);
    let blocks = 10u64;
    let ticks = blocks * 64;
    let duration = format!("{}", ticks as f64 / 199_600.0);
    let recorder = spawn(&[
        "record",
        "--json",
        "-q",
        "--prefix",
        &p,
        "--duration",
        &duration,
        "--out",
        out.to_str().unwrap(),
    ]);
    let view = spawn(&["view", "--prefix", &p, "--port", "0"]);
    let ep = Endpoint::open(&p, "test-bad-publisher").unwrap();
    let telemetry_service = ep.service::<TelemetryBlock>(leaf::TELEMETRY).unwrap();
    let truth_service = ep.service::<TruthBlock>(leaf::TRUTH).unwrap();
    // Both subscribed before anything is published (bounded: a process that never
    // subscribes fails the test).
    for _ in 0..3000 {
        if subscriber_count(&telemetry_service) >= 2 && subscriber_count(&truth_service) >= 2 {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let telemetry_pub = ep.publisher::<TelemetryBlock>(leaf::TELEMETRY).unwrap();
    let truth_pub = ep.publisher::<TruthBlock>(leaf::TRUTH).unwrap();
    daq_io::ipc::connect(&telemetry_pub);
    daq_io::ipc::connect(&truth_pub);
    let run = 0x5eed;
    let telemetry = |index: u64, seqs: std::ops::Range<u64>, end: bool, run: u64| {
        let mut b = TelemetryBlock::default();
        for seq in seqs {
            b.push(Telemetry {
                seq,
                time_s: seq as f64 / 199_600.0,
                ..Default::default()
            });
        }
        b.seal(index, if end { flags::END } else { 0 }, run);
        b
    };
    let truth = |index: u64, seqs: std::ops::Range<u64>, end: bool| {
        let mut b = TruthBlock::default();
        for seq in seqs {
            b.push(Truth {
                seq,
                time_s: seq as f64 / 199_600.0,
                ..Default::default()
            });
        }
        b.seal(index, if end { flags::END } else { 0 }, run);
        b
    };
    for k in 0..blocks {
        let seqs = 64 * k..64 * (k + 1);
        let last = k + 1 == blocks;
        assert!(send(&truth_pub, truth(k, seqs.clone(), last)));
        match k {
            3 => {
                let mut over = telemetry(k, seqs.clone(), false, run);
                over.count = 65;
                assert!(send(&telemetry_pub, over));
            }
            5 => assert!(send(&telemetry_pub, telemetry(k, 0..64, false, run))),
            7 => assert!(send(&telemetry_pub, telemetry(k, seqs.clone(), false, 7))),
            _ => {}
        }
        assert!(send(&telemetry_pub, telemetry(k, seqs, last, run)));
        std::thread::sleep(Duration::from_millis(2));
    }
    let recorder = recorder.wait_with_output().unwrap();
    let summary_text = String::from_utf8_lossy(&recorder.stdout);
    assert!(
        recorder.status.success(),
        "recorder: {:?} {}",
        recorder.status,
        String::from_utf8_lossy(&recorder.stderr)
    );
    let summary: serde_json::Value = serde_json::from_str(&summary_text).unwrap();
    assert_eq!(summary["ticks"], ticks, "{summary_text}");
    let hil = &summary["meta"]["hil"];
    assert_eq!(hil["bad_blocks"], 3, "{hil}");
    assert_eq!(
        hil["first_bad_block"],
        "telemetry block 3 says it holds 65 records, above its capacity of 64"
    );
    let read = recorder::read(&out).unwrap();
    assert_eq!(read.frames.len() as u64, ticks);
    assert!(read
        .frames
        .iter()
        .all(|f| f.telemetry.flags as u32 & flags::NO_TELEMETRY == 0));
    let end = &read.end;
    assert!(
        end.get("hil.bad_blocks")
            .is_some_and(|v| v.starts_with("3 refused; the first: telemetry block 3")),
        "{end:?}"
    );
    let view = view.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&view.stderr);
    assert!(view.status.success(), "view: {said}");
    assert!(
        said.contains(&format!("{ticks} ticks seen"))
            && said.contains("3 blocks refused and skipped")
            && said.contains("the first: telemetry block 3"),
        "{said}"
    );
}
