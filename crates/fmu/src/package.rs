//! The `.fmu` archive: the description, the x86-64 Linux binary under the model identifier's
//! name and the resources libfts_fmu reads, written whole or not at all.

use crate::{FmiVersion, DEPLOYMENT_FILE, UNIT_FILE};
use std::io::Write;
use std::path::{Path, PathBuf};

/// What goes into a unit's archive besides its binary.
#[derive(Debug, Clone)]
pub struct UnitFiles {
    /// FMI version of the description.
    pub version: FmiVersion,
    /// The archive's model identifier (the binary's name without `.so`).
    pub model_identifier: String,
    /// `modelDescription.xml`.
    pub model_description: String,
    /// `resources/unit.toml`.
    pub unit: String,
    /// `resources/deployment.toml` (the controller's).
    pub deployment: Option<String>,
}

/// Why an archive was not written.
#[derive(Debug, thiserror::Error)]
pub enum PackageError {
    /// The library to carry cannot be read.
    #[error("cannot read the FMU library {}: {source} (build it with `cargo build --release -p fmu-ffi`, or name it with FTS_FMU_LIBRARY)", path.display())]
    Library {
        /// The library's path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The archive cannot be written.
    #[error("cannot write {}: {source}", path.display())]
    Write {
        /// The archive's path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// Writes the archive of `files` with the shared library `library` to `out` and returns its
/// size in bytes. The archive is written beside `out` and moved into place when whole; an
/// existing `out` is kept (an error) unless `overwrite`.
pub fn write_fmu(
    out: &Path,
    files: &UnitFiles,
    library: &Path,
    overwrite: bool,
) -> Result<u64, PackageError> {
    let binary = std::fs::read(library).map_err(|source| PackageError::Library {
        path: library.to_owned(),
        source,
    })?;
    let write_err = |source| PackageError::Write {
        path: out.to_owned(),
        source,
    };
    if !overwrite && out.exists() {
        return Err(write_err(std::io::Error::other(
            "it exists: not overwritten (pass --overwrite to replace it)",
        )));
    }
    let mut partial = out.as_os_str().to_owned();
    partial.push(format!(".{}.partial", std::process::id()));
    let partial = PathBuf::from(partial);
    let written = archive(&partial, files, &binary).and_then(|()| {
        if overwrite {
            std::fs::rename(&partial, out)
        } else {
            // A hard link never replaces an existing file: a file made meanwhile is kept.
            std::fs::hard_link(&partial, out).and_then(|()| std::fs::remove_file(&partial))
        }
    });
    if let Err(e) = written {
        let _ = std::fs::remove_file(&partial);
        return Err(write_err(e));
    }
    std::fs::metadata(out).map(|m| m.len()).map_err(write_err)
}

fn archive(path: &Path, files: &UnitFiles, binary: &[u8]) -> std::io::Result<()> {
    let file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)?;
    let mut zip = zip::ZipWriter::new(std::io::BufWriter::new(file));
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Stored)
        .unix_permissions(0o644);
    let mut put = |name: &str, bytes: &[u8], mode: u32| -> std::io::Result<()> {
        zip.start_file(name, options.unix_permissions(mode))
            .map_err(std::io::Error::other)?;
        zip.write_all(bytes)
    };
    put(
        "modelDescription.xml",
        files.model_description.as_bytes(),
        0o644,
    )?;
    put(
        &format!(
            "{}/{}.so",
            files.version.binary_dir(),
            files.model_identifier
        ),
        binary,
        0o755,
    )?;
    put(
        &format!("resources/{UNIT_FILE}"),
        files.unit.as_bytes(),
        0o644,
    )?;
    if let Some(d) = &files.deployment {
        put(&format!("resources/{DEPLOYMENT_FILE}"), d.as_bytes(), 0o644)?;
    }
    zip.finish().map_err(std::io::Error::other)?.flush()
}
