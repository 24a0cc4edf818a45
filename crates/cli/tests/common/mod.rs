//! What the CLI tests share: the binary, a private scratch folder, JSON output.
#![allow(dead_code)] // each test file uses a part

pub mod hil;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The `servo` binary under test.
pub fn servo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_servo"))
}

/// `name` in this test's scratch folder: created exclusively with a random name, private to
/// the user (0700), made at the first call and removed when the test ends. libtest runs each
/// test on a thread of its own, so the folder is the thread's: its destructor runs when the
/// test's thread exits, passed or failed (a static would never be dropped, and every run
/// of the suite would leave its recordings behind in the shared temp folder). To look at a
/// test's files afterwards, set `FTS_KEEP_TEST_FILES=1`: the folder is kept and named on
/// stderr.
pub fn tmp(name: &str) -> PathBuf {
    thread_local! {
        static DIR: tempfile::TempDir = tempfile::Builder::new()
            .prefix("fts-cli-")
            .disable_cleanup(std::env::var_os("FTS_KEEP_TEST_FILES").is_some())
            .tempdir()
            .inspect(|d| {
                if std::env::var_os("FTS_KEEP_TEST_FILES").is_some() {
                    eprintln!("test files kept in {}", d.path().display());
                }
            })
            .expect("a private scratch folder");
    }
    DIR.with(|dir| dir.path().join(name))
}

/// `servo tune` with the flags `args`, its gains written to `name` in the scratch folder;
/// the file's path.
pub fn tuned(name: &str, args: &[&str]) -> PathBuf {
    let file = tmp(name);
    succeeded(
        &servo()
            .arg("tune")
            .args(args)
            .arg("--out")
            .arg(&file)
            .output()
            .unwrap(),
    );
    file
}

/// Asserts that `out` is a successful run, showing its stderr otherwise.
pub fn succeeded(out: &Output) {
    assert!(
        out.status.success(),
        "servo failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The JSON a successful `servo … --json` printed (panics with its stderr otherwise).
pub fn json(out: &Output) -> serde_json::Value {
    succeeded(out);
    serde_json::from_slice(&out.stdout).expect("JSON summary")
}

/// This process's effective uid (from /proc).
#[allow(dead_code)]
pub fn euid() -> u32 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("Uid:")).unwrap();
    line.split_whitespace().nth(2).unwrap().parse().unwrap()
}

/// Runs `cmd` as the unprivileged user `nobody` (uid/gid 65534).
#[allow(dead_code)]
pub fn as_nobody(mut cmd: std::process::Command) -> std::process::Output {
    use std::os::unix::process::CommandExt;
    cmd.uid(65534).gid(65534).output().unwrap()
}

/// `servo spectrum file --json --out-dir out_dir` with the flags `extra`: its JSON result.
pub fn spectrum(file: &Path, out_dir: &Path, extra: &[&str]) -> serde_json::Value {
    json(
        &servo()
            .arg("spectrum")
            .arg(file)
            .args(["--json", "--out-dir"])
            .arg(out_dir)
            .args(extra)
            .output()
            .unwrap(),
    )
}

/// Every band's recorded RMS of `signal` within `tol` of the budget's.
pub fn assert_bands_agree(s: &serde_json::Value, signal: &str, tol_percent: f64) {
    let bands = s["bands"].as_array().unwrap();
    assert!(bands.len() >= 3, "{bands:?}");
    for b in bands.iter().chain(std::iter::once(&s["total"])) {
        let rms = b.get("rms").unwrap_or(b);
        let d = rms[signal]["difference_percent"].as_f64().unwrap();
        assert!(
            d.abs() <= tol_percent,
            "{signal} {}–{} Hz: recorded {} vs budget {} ({d:+.1} %)",
            b["from_hz"],
            b["to_hz"],
            rms[signal]["recorded"],
            rms[signal]["predicted"]
        );
    }
}
