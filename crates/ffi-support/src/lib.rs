//! What the fts-servo C libraries share at the boundary: a handle's last-error text held in
//! fixed storage (written without allocating, so a real-time call may set it), panics caught
//! before they cross into C, and C strings read with their encoding checked.

use std::ffi::{c_char, CStr};
use std::fmt::{self, Write};
use std::panic::{catch_unwind, AssertUnwindSafe};

/// Bytes of error text a handle keeps (longer messages are cut at a character boundary).
pub const ERROR_BYTES: usize = 1024;

/// A message in fixed storage, NUL-terminated for C.
pub struct ErrorText {
    buf: [u8; ERROR_BYTES],
    len: usize,
}

impl Default for ErrorText {
    fn default() -> Self {
        ErrorText {
            buf: [0; ERROR_BYTES],
            len: 0,
        }
    }
}

impl Write for ErrorText {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        // Keep one byte for the NUL; cut at a character boundary.
        let room = ERROR_BYTES - 1 - self.len;
        let mut take = s.len().min(room);
        while !s.is_char_boundary(take) {
            take -= 1;
        }
        self.buf[self.len..self.len + take].copy_from_slice(&s.as_bytes()[..take]);
        self.len += take;
        self.buf[self.len] = 0;
        Ok(())
    }
}

impl ErrorText {
    /// Replaces the text with `message` (no allocation).
    pub fn set(&mut self, message: fmt::Arguments<'_>) {
        self.len = 0;
        self.buf[0] = 0;
        let _ = self.write_fmt(message);
    }

    /// Empties the text.
    pub fn clear(&mut self) {
        self.len = 0;
        self.buf[0] = 0;
    }

    /// The text as a NUL-terminated C string (valid while the owner is).
    pub fn as_ptr(&self) -> *const c_char {
        self.buf.as_ptr().cast()
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        std::str::from_utf8(&self.buf[..self.len]).unwrap_or("")
    }
}

/// Runs `f`, turning a panic into `on_panic` (a panic must never unwind into C).
pub fn guard(on_panic: i32, f: impl FnOnce() -> i32) -> i32 {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or(on_panic)
}

/// Copies `message` into the caller's buffer `out` of `len` bytes (NUL-terminated, cut to fit);
/// nothing when `out` is null or `len` is 0.
///
/// # Safety
/// `out` is null or points to `len` writable bytes.
pub unsafe fn copy_message(out: *mut c_char, len: usize, message: &str) {
    if out.is_null() || len == 0 {
        return;
    }
    let mut n = message.len().min(len - 1);
    while !message.is_char_boundary(n) {
        n -= 1;
    }
    // SAFETY: the caller gives `len` writable bytes at `out`; n + 1 ≤ len, and the source is
    // a different allocation.
    unsafe {
        std::ptr::copy_nonoverlapping(message.as_ptr(), out.cast::<u8>(), n);
        *out.add(n) = 0;
    }
}

/// Why a C string was not taken.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TextError {
    /// The pointer is null.
    Null(String),
    /// Not UTF-8, or longer than allowed: the content is at fault, not the pointer.
    Content(String),
}

impl fmt::Display for TextError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            TextError::Null(m) | TextError::Content(m) => f.write_str(m),
        }
    }
}

/// The UTF-8 text of the C string `s` of at most `limit` bytes (before its NUL), or why not:
/// null, longer (only `limit + 1` bytes are ever read), not UTF-8 (the offset named).
///
/// # Safety
/// `s` is null or points to a NUL-terminated string that stays valid and unchanged while the
/// returned text is used.
pub unsafe fn text<'a>(s: *const c_char, what: &str, limit: usize) -> Result<&'a str, TextError> {
    if s.is_null() {
        return Err(TextError::Null(format!("{what} is a null pointer")));
    }
    // Its length, looking no further than `limit + 1` bytes.
    let mut len = 0;
    // SAFETY: every byte up to and including the NUL is readable (the caller's promise), and
    // the scan stops at the NUL or one byte past `limit`, whichever comes first.
    while len <= limit && unsafe { *s.add(len) } != 0 {
        len += 1;
    }
    if len > limit {
        return Err(TextError::Content(format!(
            "{what} is longer than the {limit} bytes allowed"
        )));
    }
    // SAFETY: `len` bytes before a NUL, readable and unchanged for 'a (the caller's promise).
    let c = unsafe {
        CStr::from_bytes_with_nul_unchecked(std::slice::from_raw_parts(s.cast(), len + 1))
    };
    c.to_str().map_err(|e| {
        TextError::Content(format!(
            "{what} is not UTF-8 text (invalid byte at offset {})",
            e.valid_up_to()
        ))
    })
}

/// Writes the pkg-config file `NAME.pc` and the CMake package file `NAME-config.cmake` of the
/// C library `NAME` (`libNAME.so`, `libNAME.a`) beside the libraries of the build running this
/// build script, pointing at them and at the checkout's `include/`: a C build finds them with
/// `PKG_CONFIG_PATH=target/release` or `find_package(NAME CONFIG PATHS target/release)`.
pub fn write_package_files(name: &str, description: &str) {
    use std::path::PathBuf;
    let env = |k: &str| std::env::var(k).unwrap_or_default();
    let out = PathBuf::from(env("OUT_DIR"));
    // OUT_DIR is <target>/<profile>/build/<crate>-<hash>/out.
    let Some(libdir) = out.ancestors().nth(3) else {
        return;
    };
    let include = PathBuf::from(env("CARGO_MANIFEST_DIR")).join("../../include");
    let include = include.canonicalize().unwrap_or(include);
    let (lib, inc) = (libdir.display(), include.display());
    let version = env("CARGO_PKG_VERSION");
    let pc = format!(
        "libdir={lib}\nincludedir={inc}\n\nName: {name}\nDescription: {description}\nVersion: {version}\n\
         Libs: -L${{libdir}} -l{name}\nLibs.private: -lpthread -ldl -lm -lrt\nCflags: -I${{includedir}}\n"
    );
    let cmake = format!(
        "# {description}\n# find_package({name} CONFIG PATHS {lib}) gives the target {name}::{name}.\n\
         add_library({name}::{name} SHARED IMPORTED)\n\
         set_target_properties({name}::{name} PROPERTIES\n  IMPORTED_LOCATION \"{lib}/lib{name}.so\"\n  \
         INTERFACE_INCLUDE_DIRECTORIES \"{inc}\")\nset({name}_FOUND TRUE)\n"
    );
    let _ = std::fs::write(libdir.join(format!("{name}.pc")), pc);
    let _ = std::fs::write(libdir.join(format!("{name}-config.cmake")), cmake);
}

/// Checks that `include/HEADER` of the checkout is what cbindgen makes of the crate at
/// `crate_dir` with its `cbindgen.toml`; with `FTS_WRITE_HEADERS=1`, rewrites it instead.
///
/// # Panics
/// When the header is stale (the test's failure), or cbindgen cannot read the crate.
#[cfg(feature = "header")]
pub fn check_header(crate_dir: &str, header: &str) {
    let path = std::path::Path::new(crate_dir)
        .join("../../include")
        .join(header);
    let config = cbindgen::Config::from_root_or_default(crate_dir);
    let bindings = cbindgen::Builder::new()
        .with_config(config)
        .with_crate(crate_dir)
        .generate()
        .expect("cbindgen reads the crate");
    let mut generated = Vec::new();
    bindings.write(&mut generated);
    if std::env::var_os("FTS_WRITE_HEADERS").is_some() {
        std::fs::write(&path, &generated).expect("the header is writable");
        return;
    }
    let checked_in = std::fs::read(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "{} is stale: regenerate it with FTS_WRITE_HEADERS=1 cargo test --test header",
        path.display()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_text_is_cut_at_a_character_and_terminated() {
        let mut e = ErrorText::default();
        e.set(format_args!("{}", "µ".repeat(2000)));
        assert_eq!(e.as_str().len(), ERROR_BYTES - 2);
        assert!(e.as_str().chars().all(|c| c == 'µ'));
        e.set(format_args!("short {}", 1));
        assert_eq!(e.as_str(), "short 1");
        let mut out = [1 as c_char; 4];
        // SAFETY: four writable bytes.
        unsafe { copy_message(out.as_mut_ptr(), out.len(), "abcdef") };
        assert_eq!(out.map(|c| c as u8), *b"abc\0");
        assert_eq!(guard(-8, || panic!("inside")), -8);
    }
}
