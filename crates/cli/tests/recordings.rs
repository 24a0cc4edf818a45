//! Recordings end to end: what a run leaves on disk however it ends, and reading it back.

use crate::common;

use common::{json, servo, succeeded, tmp};
use std::process::{Command, Stdio};

/// What `servo inspect --json` says of the recording `path`.
fn inspect_json(path: &std::path::Path) -> serde_json::Value {
    json(
        &servo()
            .args(["inspect", "--json"])
            .arg(path)
            .output()
            .unwrap(),
    )
}

/// The JSON summary of `servo run --json -q ARGS --out PATH`.
fn live_summary(path: &std::path::Path, args: &[&str]) -> serde_json::Value {
    json(
        &servo()
            .args(["run", "--json", "-q"])
            .args(args)
            .arg("--out")
            .arg(path)
            .output()
            .unwrap(),
    )
}

/// The default run writes an MCAP that the official reader decodes completely, and `servo
/// inspect` recomputes exactly the live statistics from it.
#[test]
fn inspect_equals_the_live_summary() {
    let path = tmp("live.mcap");
    let live = live_summary(&path, &["--duration", "0.3"]);
    let read = inspect_json(&path);
    for key in [
        "ticks",
        "stats_ticks",
        "following_error_m",
        "true_error_m",
        "control_v",
        "saturated_ticks",
        "adc_clipped_ticks",
    ] {
        assert_eq!(live[key], read["summary"][key], "{key}");
    }
    assert_eq!(read["end"]["reason"], "completed");
    assert!(read["file"].as_str().unwrap().starts_with("complete"));
    let rec = recorder::read(&path).unwrap();
    let messages = rec.report.unwrap().messages;
    assert_eq!(messages, 2 * live["ticks"].as_u64().unwrap());
    assert_eq!(live["meta"]["recorded_messages"].as_u64(), Some(messages));
}

/// `--record-every 10`: a tenth of the ticks, a finished run (not "interrupted"), and
/// statistics close to the live ones (the RMS of a tenth of 60 000 noisy samples: within 5 %).
#[test]
fn a_decimated_recording_reads_as_a_complete_run() {
    let path = tmp("every10.mcap");
    let live = live_summary(&path, &["--duration", "0.3", "--record-every", "10"]);
    let read = inspect_json(&path);
    let s = &read["summary"];
    assert_eq!(s["ticks"], live["ticks"].as_u64().unwrap().div_ceil(10));
    assert_eq!(s["meta"]["interrupted"], false);
    assert_eq!(s["meta"]["recorded_every"], 10);
    assert_eq!(read["end"]["reason"], "completed");
    let rms = |v: &serde_json::Value| v["following_error_m"]["rms"].as_f64().unwrap();
    assert!(
        (rms(s) / rms(&live) - 1.0).abs() < 0.05,
        "{} vs {}",
        rms(s),
        rms(&live)
    );
}

/// Same seed, same data: every message, attachment and record but the run's environment
/// (run id, host, start time) is byte-identical, and the environment does differ.
#[test]
fn same_seed_gives_identical_data() {
    let (a, b) = (tmp("a.mcap"), tmp("b.mcap"));
    for p in [&a, &b] {
        let st = servo()
            .args(["run", "-q", "--duration", "0.1", "--seed", "5", "--out"])
            .arg(p)
            .output()
            .unwrap();
        assert!(st.status.success());
    }
    assert_eq!(
        recorder::fingerprint(&a).unwrap(),
        recorder::fingerprint(&b).unwrap()
    );
    let environment = |p| {
        let mut e = Environment(Default::default());
        recorder::stream(p, &mut e).unwrap();
        e.0
    };
    let (ea, eb) = (environment(&a), environment(&b));
    assert_ne!(ea["run_id"], eb["run_id"]);
    assert_eq!(ea["version"], env!("CARGO_PKG_VERSION"));
}

/// The `environment` record of a recording.
struct Environment(std::collections::BTreeMap<String, String>);

impl recorder::Visit for Environment {
    fn metadata(&mut self, name: &str, values: &std::collections::BTreeMap<String, String>) {
        if name == "environment" {
            self.0 = values.clone();
        }
    }
}

/// Bytes of a recording that show its run is ticking (its signal handlers are installed
/// before its file is opened): a few chunks of frames.
const RECORDING_UNDER_WAY: u64 = 256 << 10;

/// Waits until process `pid`'s recording to `path`, written as `<path>.<pid>.partial` until
/// it is finished, holds `bytes` (bounded: a minute).
fn recording_grows(path: &std::path::Path, pid: u32, bytes: u64) {
    let partial = format!("{}.{pid}.partial", path.display());
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < bytes {
        assert!(
            std::time::Instant::now() < deadline,
            "{partial} never reached {bytes} bytes"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// SIGINT, SIGTERM or SIGHUP mid-run: the run ends at a tick boundary, the MCAP is finished
/// and readable, its `end` record names the signal, and the exit code is 128 + its number.
#[test]
fn a_signal_ends_the_run_with_a_finished_file_that_names_it() {
    for (signal, name, code) in [
        ("INT", "SIGINT", 130),
        ("TERM", "SIGTERM", 143),
        ("HUP", "SIGHUP", 129),
    ] {
        let path = tmp(&format!("sig-{signal}.mcap"));
        let child = servo()
            .args(["run", "--json", "-q", "--duration", "600", "--out"])
            .arg(&path)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        recording_grows(&path, child.id(), RECORDING_UNDER_WAY);
        let ok = Command::new("kill")
            .args([&format!("-{signal}"), &child.id().to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(code),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["meta"]["interrupted"], true);
        assert_eq!(v["meta"]["end_reason"], "interrupted");
        let ticks = v["ticks"].as_u64().unwrap();
        assert!(ticks > 0 && ticks < 600 * 199_600);
        let rec = recorder::read(&path).expect("a finished MCAP");
        assert_eq!(rec.report.unwrap().state, recorder::FileState::Finished);
        assert_eq!(rec.frames.len() as u64, ticks);
        assert_eq!(rec.end["signal"], name);
        assert_eq!(rec.end["ticks"], ticks.to_string());
        let read = inspect_json(&path);
        assert_eq!(read["summary"]["meta"]["interrupted"], true);
        assert_eq!(read["summary"]["following_error_m"], v["following_error_m"]);
    }
}

/// A second run to the same file is refused (exit 2, the file named, nothing changed);
/// `--overwrite` replaces it.
#[test]
fn an_existing_recording_is_not_overwritten() {
    let path = tmp("twice.mcap");
    let run = |extra: &[&str]| {
        servo()
            .args(["run", "-q", "--duration", "0.01", "--out"])
            .arg(&path)
            .args(extra)
            .output()
            .unwrap()
    };
    assert!(run(&[]).status.success());
    let first = std::fs::read(&path).unwrap();
    let again = run(&["--seed", "9"]);
    assert_eq!(again.status.code(), Some(1));
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(
        err.contains("twice.mcap") && err.contains("--overwrite"),
        "{err}"
    );
    assert_eq!(std::fs::read(&path).unwrap(), first);
    assert!(run(&["--seed", "9", "--overwrite"]).status.success());
    assert_ne!(std::fs::read(&path).unwrap(), first);
}

/// A recording never makes `servo inspect` open a path named inside it: the controller file
/// of a state-space run is deleted before the inspection, which still works (the
/// controller's description and its file are in the recording itself).
#[test]
fn inspect_reads_nothing_but_the_recording() {
    let dir = tmp("selfcontained");
    std::fs::create_dir_all(&dir).unwrap();
    let ctrl = dir.join("h2.toml");
    let synth = servo()
        .args(["synth", "h2", "--rate", "20000", "--order", "8", "--out"])
        .arg(&ctrl)
        .output()
        .unwrap();
    succeeded(&synth);
    let rec = dir.join("ss.mcap");
    let run = servo()
        .args([
            "run",
            "-q",
            "--rate",
            "20000",
            "--duration",
            "0.05",
            "--controller",
            "ss",
            "--ss-file",
        ])
        .arg(&ctrl)
        .arg("--out")
        .arg(&rec)
        .output()
        .unwrap();
    succeeded(&run);
    std::fs::remove_file(&ctrl).unwrap();
    let read = inspect_json(&rec);
    assert!(
        read["summary"]["meta"]["controller"]
            .as_str()
            .unwrap()
            .starts_with("state space, 8 states"),
        "{read}"
    );
}

/// A device is never taken for a recording (not even with --overwrite): a clear error naming
/// it, nothing run.
#[test]
fn a_device_is_not_a_recording_target() {
    let out = servo()
        .args([
            "run",
            "-q",
            "--duration",
            "1",
            "--overwrite",
            "--out",
            "/dev/full",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("/dev/full") && err.contains("not a regular file"),
        "{err}"
    );
}

/// A file-size limit reached mid-run (`ulimit -f`, here 2 MB; its SIGXFSZ left to servo, as a
/// shell leaves it) ends the run safely with a clear error naming the target (exit 4, no
/// panic, not killed by the signal), and the recording is finished with the part that fit:
/// shorter, readable as a whole run whose `end` record says why, holding exactly the start of
/// the same seeded run.
#[test]
fn a_full_disk_mid_run_ends_the_run_with_a_finished_shorter_file() {
    let dir = tmp("fulldisk");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("big.mcap");
    let script = format!(
        "ulimit -f 4000; exec '{}' run -q --duration 5 --out '{}'",
        env!("CARGO_BIN_EXE_servo"),
        path.display()
    );
    let out = Command::new("sh").args(["-c", &script]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(4), "{err}");
    assert!(
        err.contains("big.mcap")
            && err.contains("too large")
            && err.contains("finished with the part that fit"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(left, std::slice::from_ref(&path), "no partial file is left");
    assert!(std::fs::metadata(&path).unwrap().len() <= 4000 * 512);
    let read = inspect_json(&path);
    assert!(
        read["file"].as_str().unwrap().starts_with("complete"),
        "{read}"
    );
    assert_eq!(
        read["end"]["recorded_ticks"],
        read["summary"]["ticks"].to_string()
    );
    assert_eq!(read["summary"]["meta"]["end_reason"], "write-failed");
    let ticks = read["summary"]["ticks"].as_u64().unwrap();
    assert!(ticks > 10_000, "{read}");
    let kept = ticks as f64 / 199_600.0;
    assert!(kept < 1.0, "2 MB cannot hold {kept} s");
    // Exactly the start of the same run.
    let whole = dir.join("whole.mcap");
    let duration = format!("{}", (ticks + 1000) as f64 / 199_600.0);
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", &duration, "--out"])
            .arg(&whole)
            .output()
            .unwrap(),
    );
    let (short, whole) = (
        recorder::read(&path).unwrap().frames,
        recorder::read(&whole).unwrap().frames,
    );
    assert_eq!(short.len() as u64, ticks);
    assert_eq!(short[..], whole[..short.len()]);
}

/// A run killed with SIGKILL (no handler runs) leaves its `.partial` file: every complete
/// chunk in it is recovered, and what is recovered is exactly the start of the same seeded
/// run left to finish.
#[test]
fn a_sigkilled_run_is_recovered_up_to_its_last_chunk() {
    let path = tmp("killed.mcap");
    let mut child = servo()
        .args(["run", "-q", "--duration", "1", "--seed", "3", "--out"])
        .arg(&path)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let partial = recorder::partial_path_of(&path, child.id());
    // Kill once a few chunks are on disk (2 MB ≈ 0.15 s of run); a slow machine only waits
    // longer.
    while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 2 << 20 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "finished before the kill"
        );
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let killed = recorder::read(&partial).unwrap();
    let report = killed.report.unwrap();
    assert_eq!(report.state, recorder::FileState::Unfinished);
    assert!(report.to_string().starts_with("unfinished"), "{report}");
    let whole = tmp("unkilled.mcap");
    succeeded(
        &servo()
            .args(["run", "-q", "--duration", "1", "--seed", "3", "--out"])
            .arg(&whole)
            .output()
            .unwrap(),
    );
    let reference = recorder::read(&whole).unwrap().frames;
    let n = killed.frames.len();
    // At least the 2 MB seen on disk: well over one 20 ms chunk (≈ 4 000 ticks).
    assert!(n > 8_000 && n < reference.len(), "{n} frames recovered");
    assert!(
        killed.frames[..] == reference[..n],
        "the recovered frames differ"
    );
    assert_eq!(n % 3_992, 0, "whole 20 ms chunks (3 992 ticks each) only");
}

/// Peak resident memory of `servo inspect file`, kB (Python's getrusage of its only child).
fn inspect_peak_rss_kb(file: &std::path::Path) -> u64 {
    let out = Command::new("python3")
        .args([
            "-c",
            "import resource, subprocess, sys\n\
             subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)\n\
             print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)",
            env!("CARGO_BIN_EXE_servo"),
            "inspect",
        ])
        .arg(file)
        .output()
        .unwrap();
    succeeded(&out);
    String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
}

/// `servo inspect` streams: a recording ten times longer needs no more memory.
#[test]
fn inspect_memory_does_not_grow_with_the_recording() {
    let (short, long) = (tmp("short.mcap"), tmp("long.mcap"));
    for (p, seconds) in [(&short, "0.2"), (&long, "2")] {
        succeeded(
            &servo()
                .args(["run", "-q", "--duration", seconds, "--out"])
                .arg(p)
                .output()
                .unwrap(),
        );
    }
    let size = |p: &std::path::Path| std::fs::metadata(p).unwrap().len();
    assert!(size(&long) > 9 * size(&short));
    let (a, b) = (inspect_peak_rss_kb(&short), inspect_peak_rss_kb(&long));
    assert!(
        b < a + a / 10,
        "peak RSS {a} kB for {} B, {b} kB for {} B",
        size(&short),
        size(&long)
    );
}

/// `--split-s`: a run written in parts, each intact on its own (`servo inspect` exit 0, its
/// ticks as its `end` record counts), following on from the part before, together the run's
/// ticks; the first part replays bit for bit and a later one is refused with the first's name.
#[test]
fn a_split_run_is_whole_parts_that_add_up_to_the_run() {
    let path = tmp("split.mcap");
    let live = live_summary(&path, &["--duration", "0.25", "--split-s", "0.1"]);
    assert!(!path.exists());
    let mut ticks = 0;
    for part in 0..3 {
        let file = tmp(&format!("split_{part:05}.mcap"));
        let read = inspect_json(&file);
        assert_eq!(read["end"]["part"], part.to_string());
        assert_eq!(read["end"]["part_first_tick"], ticks.to_string());
        assert_eq!(
            read["summary"]["ticks"].to_string(),
            read["end"]["part_ticks"].as_str().unwrap()
        );
        ticks += read["summary"]["ticks"].as_u64().unwrap();
        let reason = if part < 2 { "split" } else { "completed" };
        assert_eq!(read["end"]["reason"], reason);
    }
    assert!(!tmp("split_00003.mcap").exists());
    assert_eq!(
        live["ticks"].as_u64().unwrap(),
        ticks,
        "the parts hold every tick"
    );

    let replayed = servo()
        .args(["replay", "-q", "--no-record"])
        .arg(tmp("split_00000.mcap"))
        .output()
        .unwrap();
    succeeded(&replayed);
    let text = String::from_utf8_lossy(&replayed.stdout);
    assert!(text.contains("identical, bit for bit"), "{text}");
    let later = servo()
        .args(["replay", "-q", "--no-record"])
        .arg(tmp("split_00001.mcap"))
        .output()
        .unwrap();
    assert_eq!(later.status.code(), Some(1));
    let why = String::from_utf8_lossy(&later.stderr);
    assert!(
        why.contains("part 1 of a split recording") && why.contains("split_00000.mcap"),
        "{why}"
    );
}
