//! Opening the files a user names — configurations, controller files, images, CSVs,
//! recordings, journals, paths named inside recordings — so that none can block or exhaust:
//! the path is checked to be a regular file of bounded size *before* it is opened (opening a
//! FIFO with no writer blocks in `open`; opening a device can act on it), opened without
//! blocking and without becoming a controlling terminal, and checked again on the open file
//! (the same file, still regular: a swap between the two checks is refused).

use std::fs::File;
use std::io::{Error, ErrorKind, Read};
use std::os::unix::fs::{FileTypeExt, MetadataExt, OpenOptionsExt};
use std::path::Path;

/// What a non-regular file is, for the error.
fn kind(t: std::fs::FileType) -> &'static str {
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// The regular file `path`, open for reading, of at most `limit` bytes (its length returned
/// beside it). Errors name what the path is instead.
pub fn open_regular(path: &Path, limit: u64) -> std::io::Result<(File, u64)> {
    let before = std::fs::metadata(path)?;
    let check = |m: &std::fs::Metadata| -> std::io::Result<()> {
        if !m.is_file() {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("{}, not a regular file", kind(m.file_type())),
            ));
        }
        if m.len() > limit {
            return Err(Error::new(
                ErrorKind::InvalidInput,
                format!("{} bytes, more than the {limit} allowed", m.len()),
            ));
        }
        Ok(())
    };
    check(&before)?;
    let flags = nix::fcntl::OFlag::O_NONBLOCK | nix::fcntl::OFlag::O_NOCTTY;
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(flags.bits())
        .open(path)?;
    let after = file.metadata()?;
    check(&after)?;
    if (after.dev(), after.ino()) != (before.dev(), before.ino()) {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            "the file changed while it was being opened",
        ));
    }
    Ok((file, after.len()))
}

/// The bytes of the regular file `path`, at most `limit` of them (a file that grows past the
/// limit while read is refused).
pub fn read_regular(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    let (file, len) = open_regular(path, limit)?;
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(Error::new(
            ErrorKind::InvalidInput,
            format!("more than the {limit} bytes allowed"),
        ));
    }
    Ok(bytes)
}

/// The UTF-8 text of the regular file `path`, at most `limit` bytes, without the byte-order
/// mark a spreadsheet or an editor may put first.
pub fn read_regular_text(path: &Path, limit: u64) -> std::io::Result<String> {
    text_of(read_regular(path, limit)?)
}

/// `bytes` as UTF-8 text without a leading byte-order mark; the error says where the text
/// stops being UTF-8.
pub fn text_of(bytes: Vec<u8>) -> std::io::Result<String> {
    let mut text = String::from_utf8(bytes).map_err(|e| {
        Error::new(
            ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A FIFO, a character device and a directory are refused at once, naming what they are;
    /// a regular file over the limit too.
    #[test]
    fn only_bounded_regular_files_open() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path().to_owned();
        let fifo = dir.join("fifo");
        nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
        for (path, what) in [
            (fifo.as_path(), "a FIFO"),
            (Path::new("/dev/zero"), "a character device"),
            (dir.as_path(), "a directory"),
        ] {
            let e = read_regular(path, 1 << 20).unwrap_err();
            assert!(e.to_string().contains(what), "{}: {e}", path.display());
        }
        let file = dir.join("f");
        std::fs::write(&file, b"12345").unwrap();
        assert_eq!(read_regular(&file, 5).unwrap(), b"12345");
        assert!(read_regular(&file, 4).is_err());
    }

    /// A spreadsheet's CSV starts with a byte-order mark: the text is read without it; bytes
    /// that are not UTF-8 are named with their offset.
    #[test]
    fn text_without_its_byte_order_mark() {
        let scratch = tempfile::tempdir().unwrap();
        let file = scratch.path().join("t.csv");
        std::fs::write(&file, "\u{feff}freq_hz,gain\n1,2\n").unwrap();
        assert_eq!(
            read_regular_text(&file, 100).unwrap(),
            "freq_hz,gain\n1,2\n"
        );
        std::fs::write(&file, b"ok\xff").unwrap();
        let e = read_regular_text(&file, 100).unwrap_err();
        assert!(e.to_string().contains("offset 2"), "{e}");
    }
}
