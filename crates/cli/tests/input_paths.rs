//! Every input path is checked before it is opened: a FIFO (whose `open` would block with no
//! writer), a character device and a directory, given wherever a command reads a file —
//! configuration, plant file, controller file, surface image, FRF CSV, recording, a controller
//! to load into a run — are each refused with a message naming what the path is (never
//! blocking in `open`: a FIFO given to a command that opened it could not hang the test).

use crate::common;

use common::{servo, tmp};
use std::path::Path;

/// Runs `servo args… path` to its end and returns (exit code, stderr). No clock: if `path`
/// is a FIFO, a writer opens it beside the command, so a command that opened it (and would
/// block in `open` for want of a writer) goes on and fails the message check instead of
/// hanging the test; the writer is then released by a reader of our own.
fn refused(args: &[&str], path: &Path) -> (Option<i32>, String) {
    let fifo = std::fs::metadata(path).is_ok_and(|m| {
        use std::os::unix::fs::FileTypeExt;
        m.file_type().is_fifo()
    });
    let writer = fifo.then(|| {
        let p = path.to_owned();
        std::thread::spawn(move || drop(std::fs::OpenOptions::new().write(true).open(p)))
    });
    let out = servo()
        .args(args)
        .arg(path)
        .stdout(std::process::Stdio::null())
        .output()
        .unwrap();
    if let Some(w) = writer {
        use std::os::unix::fs::OpenOptionsExt;
        let _reader = std::fs::OpenOptions::new()
            .read(true)
            .custom_flags(nix::fcntl::OFlag::O_NONBLOCK.bits())
            .open(path);
        w.join().unwrap();
    }
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
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
            let (code, err) = refused(args, path);
            assert!(
                code.is_some_and(|c| c != 0) && err.contains(what),
                "servo {args:?} {}: exit {code:?}\n{err}",
                path.display()
            );
        }
    }
}
