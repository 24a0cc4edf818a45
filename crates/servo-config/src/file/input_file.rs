//! Reading the files a run depends on, bounded: only regular files, at most a stated size, so
//! a path naming a device, a FIFO or a huge file fails at once with a clear error
//! ([`daq_io::input_file`]: checked before it is opened, opened without blocking, checked
//! again).

use super::origin::ConfigError;
use std::path::Path;

/// Largest configuration or controller file, bytes.
pub const MAX_TEXT_BYTES: u64 = 4 << 20;
/// Largest surface image, bytes.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;

/// The bytes of the regular file `path`, at most `limit` of them.
pub fn read_input(path: &Path, limit: u64) -> Result<Vec<u8>, ConfigError> {
    daq_io::input_file::read_regular(path, limit).map_err(|source| ConfigError::Io {
        path: path.to_owned(),
        source,
    })
}

/// The UTF-8 text of the regular file `path` (at most [`MAX_TEXT_BYTES`]; a leading byte-order
/// mark dropped).
pub fn read_text(path: &Path) -> Result<String, ConfigError> {
    daq_io::input_file::read_regular_text(path, MAX_TEXT_BYTES).map_err(|source| ConfigError::Io {
        path: path.to_owned(),
        source,
    })
}

/// The name a controller file loaded into a running loop takes in messages (it has no path).
pub const LOADED_FILE: &str = "controller loaded into the running loop";
