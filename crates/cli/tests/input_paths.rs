//! Every input path is checked before it is opened: a FIFO (whose `open` would block with no
//! writer), a character device and a directory, given wherever a command reads a file —
//! configuration, plant file, controller file, surface image, FRF CSV, recording, a controller
//! to load into a run — are each refused at once with a message naming what the path is.

mod common;

use common::{servo, tmp};
use std::path::Path;
use std::time::{Duration, Instant};

/// Runs `servo args… path` and returns (exit code, stderr); fails if it takes over 20 s.
fn refused_in_time(args: &[&str], path: &Path) -> (Option<i32>, String) {
    let mut child = servo()
        .args(args)
        .arg(path)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            use std::io::Read;
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut err)
                .unwrap();
            return (status.code(), err);
        }
        if start.elapsed() > Duration::from_secs(20) {
            let _ = child.kill();
            panic!("servo {args:?} {} still running after 20 s", path.display());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn fifos_devices_and_directories_are_refused_at_every_input() {
    let dir = tmp("inputs");
    std::fs::create_dir_all(&dir).unwrap();
    let fifo = dir.join("fifo");
    let made = std::process::Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap();
    assert!(made.success());
    let commands: [&[&str]; 11] = [
        &["run", "--no-record", "-c"],
        &["run", "--no-record", "--plant"],
        &["run", "--no-record", "--controller", "ss", "--ss-file"],
        &["machine", "--no-record", "--surface", "image", "--image"],
        &["identify"],
        &["inspect"],
        &["export"],
        &["spectrum"],
        &["replay", "--no-record"],
        &["tune", "-c"],
        &["ctl", "--prefix", "no-such-run", "load"],
    ];
    for (path, what) in [
        (fifo.as_path(), "a FIFO"),
        (Path::new("/dev/zero"), "a character device"),
        (dir.as_path(), "a directory"),
    ] {
        for args in commands {
            let (code, err) = refused_in_time(args, path);
            assert!(
                code.is_some_and(|c| c != 0) && err.contains(what),
                "servo {args:?} {}: exit {code:?}\n{err}",
                path.display()
            );
        }
    }
}
