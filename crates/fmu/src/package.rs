//! The `.fmu` archive: the description, the x86-64 Linux binary under the model identifier's
//! name and the resources libfts_fmu reads.

use crate::{FmiVersion, DEPLOYMENT_FILE, UNIT_FILE};
use std::io::Write;

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

/// Writes the archive of `files` with the shared library `binary` (its bytes) to `out`:
/// `modelDescription.xml`, the binary under the model identifier's name in the platform's
/// folder, the resources.
pub fn write_archive(
    out: impl std::io::Write + std::io::Seek,
    files: &UnitFiles,
    binary: &[u8],
) -> std::io::Result<()> {
    let mut zip = zip::ZipWriter::new(out);
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
