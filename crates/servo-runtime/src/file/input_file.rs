//! Reading the files a run depends on, bounded: only regular files, at most a stated size, so
//! a path naming a device, a FIFO or a huge file fails at once with a clear error. The file is
//! opened without blocking (a FIFO with no writer would otherwise hang in `open`) and checked
//! to be a regular file before a byte is read.

use super::origin::ConfigError;
use std::io::Read;
use std::os::unix::fs::OpenOptionsExt;
use std::path::Path;

/// Largest configuration or controller file, bytes.
pub const MAX_TEXT_BYTES: u64 = 4 << 20;
/// Largest surface image, bytes.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;

/// The bytes of the regular file `path`, at most `limit` of them.
pub fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, ConfigError> {
    let err = |source: std::io::Error| ConfigError::Io {
        path: path.to_owned(),
        source,
    };
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(nix::fcntl::OFlag::O_NONBLOCK.bits())
        .open(path)
        .map_err(err)?;
    let meta = file.metadata().map_err(err)?;
    if !meta.is_file() {
        return Err(err(std::io::Error::other("not a regular file")));
    }
    let mut bytes = Vec::with_capacity(meta.len().min(limit) as usize);
    file.take(limit + 1).read_to_end(&mut bytes).map_err(err)?;
    if bytes.len() as u64 > limit {
        return Err(err(std::io::Error::other(format!(
            "larger than {limit} bytes"
        ))));
    }
    Ok(bytes)
}

/// The UTF-8 text of the regular file `path` (at most [`MAX_TEXT_BYTES`]).
pub fn read_text(path: &Path) -> Result<String, ConfigError> {
    String::from_utf8(read_input(path, MAX_TEXT_BYTES)?).map_err(|e| ConfigError::Io {
        path: path.to_owned(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
    })
}
