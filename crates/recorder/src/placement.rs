//! Where a recording (or an export) is written: a private file under a temporary name beside
//! the target, moved into place when finished, never replacing what may not be replaced.

use crate::error::RecordError;
use std::fs::File;
use std::path::{Path, PathBuf};

/// Whether an existing file at the target may be replaced.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Overwrite {
    /// Keep it: creating the recording fails with [`RecordError::Exists`].
    Refuse,
    /// Replace it when the new recording is finished.
    Replace,
}

impl Overwrite {
    /// From a command's `--overwrite` flag.
    pub fn from_flag(replace: bool) -> Self {
        if replace {
            Overwrite::Replace
        } else {
            Overwrite::Refuse
        }
    }
}

/// Whether a recording may be written to `path`: a device, a directory or a link is never
/// replaced; an existing file only with [`Overwrite::Replace`]. [`crate::Recorder::create`] checks
/// this; a caller that starts other work first (the HIL processes) can check it earlier.
pub fn check_target(path: &Path, overwrite: Overwrite) -> Result<(), RecordError> {
    let Ok(existing) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    if !existing.is_file() {
        return Err(RecordError::Io {
            path: path.to_owned(),
            source: std::io::Error::other("exists and is not a regular file"),
        });
    }
    if overwrite == Overwrite::Refuse {
        return Err(RecordError::Exists {
            path: path.to_owned(),
        });
    }
    Ok(())
}

/// Creates `path` exclusively (never through an existing file or link), mode 0600: private to
/// the user, as every file the runtime writes.
pub fn create_private(path: &Path) -> std::io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    File::options()
        .write(true)
        .create_new(true)
        .mode(0o600)
        .open(path)
}

/// `<dir>/<name>.<pid>.partial`: the recording while this process writes it.
pub fn partial_path(path: &Path) -> PathBuf {
    partial_path_of(path, std::process::id())
}

/// The `.partial` file process `pid` writes while recording to `path`.
pub fn partial_path_of(path: &Path, pid: u32) -> PathBuf {
    let name = path
        .file_name()
        .map_or_else(|| "recording".into(), |n| n.to_string_lossy().into_owned());
    path.with_file_name(format!("{name}.{pid}.partial"))
}

/// Moves the finished `partial` file to `target`: without replacing an existing one (a hard
/// link fails if `target` exists, atomically) unless `overwrite` is `Replace`.
pub fn publish(partial: &Path, target: &Path, overwrite: Overwrite) -> Result<(), RecordError> {
    let io = |source| RecordError::Io {
        path: target.to_owned(),
        source,
    };
    match overwrite {
        Overwrite::Replace => std::fs::rename(partial, target).map_err(io),
        Overwrite::Refuse => match std::fs::hard_link(partial, target) {
            Ok(()) => std::fs::remove_file(partial).map_err(io),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(RecordError::Exists {
                path: target.to_owned(),
            }),
            // Filesystems without hard links: check, then rename.
            Err(_) if !target.exists() => std::fs::rename(partial, target).map_err(io),
            Err(e) => Err(io(e)),
        },
    }
}
