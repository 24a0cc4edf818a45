//! What the CLI tests share: the binary, a private scratch folder, JSON output.
#![allow(dead_code)] // each test file uses a part

pub mod hil;

use std::path::PathBuf;
use std::process::{Command, Output};

/// The `servo` binary under test.
pub fn servo() -> Command {
    Command::new(env!("CARGO_BIN_EXE_servo"))
}

/// `name` in this test process's scratch folder: created exclusively with a random name,
/// private to the user (0700), made at the first call and kept for the process.
pub fn tmp(name: &str) -> PathBuf {
    static DIR: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        tempfile::Builder::new()
            .prefix("fts-cli-")
            .tempdir()
            .unwrap()
    })
    .path()
    .join(name)
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
