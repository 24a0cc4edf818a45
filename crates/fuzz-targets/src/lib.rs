//! # fuzz-targets
//!
//! Every decoder of bytes from outside the process, as a function of arbitrary bytes: run and
//! deployment files, plant, prescription and controller files, FRF and sag-grid CSV, MCAP
//! recordings, the processor-in-the-loop link and its deployment image, the C ABI's
//! `fts_servo_open_toml`, the live view's WebSocket messages. Each goes through the entry point
//! a user's bytes take (the plan's construction, `Servo::from_toml`, the reader and verifier,
//! the firmware's frame dispatch), not only the parser under it. A target returns normally on
//! any input (saying whether it was accepted); a panic, a hang or an allocation beyond the fuzzer's limit is a fault.
//!
//! The libFuzzer harness in `fuzz/` (cargo-fuzz, nightly) runs them in campaigns
//! (`scripts/fuzz_campaign.sh`); `tests/corpora.rs` replays the committed corpora on stable.

mod deployment;
mod files;
mod link;
mod live_view;
mod recording;

use std::path::PathBuf;

/// A private folder for the targets whose entry point reads files (made once per process).
pub struct Scratch {
    dir: tempfile::TempDir,
}

impl Scratch {
    /// A new private folder under the system's temporary directory (or `FTS_FUZZ_SCRATCH`).
    pub fn new() -> std::io::Result<Self> {
        let under = std::env::var_os("FTS_FUZZ_SCRATCH")
            .map(PathBuf::from)
            .unwrap_or_else(std::env::temp_dir);
        Ok(Scratch {
            dir: tempfile::Builder::new()
                .prefix("fts-fuzz-")
                .tempdir_in(under)?,
        })
    }

    /// Writes `bytes` as `name` in the folder; its path.
    fn file(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.dir.path().join(name);
        std::fs::write(&path, bytes).expect("the scratch folder is writable");
        path
    }

    /// Empties the folder, then writes an input that may carry the files it refers to: the
    /// main file `name` up to the first line `#--OTHER--`, then each such section as the file
    /// `OTHER` beside it (a plain name: letters, digits, `.`, `_`, `-`; other sections stay in
    /// the file before them). The main file's path.
    fn files(&self, name: &str, data: &[u8]) -> PathBuf {
        for entry in std::fs::read_dir(self.dir.path()).expect("the scratch folder") {
            let _ = std::fs::remove_file(entry.expect("an entry").path());
        }
        let mut sections = split_sections(data).into_iter();
        let (_, main) = sections.next().expect("the main section");
        let path = self.file(name, main);
        for (other, bytes) in sections {
            self.file(other, bytes);
        }
        path
    }
}

/// `data` split at its lines `#--NAME--`: the first section (unnamed), then each named one
/// (a section ends before the newline that precedes the next one's marker).
fn split_sections(data: &[u8]) -> Vec<(&str, &[u8])> {
    let mut sections = Vec::new();
    let (mut name, mut start, mut at) = ("", 0, 0usize);
    for line in data.split_inclusive(|&b| b == b'\n') {
        if let Some(next) = section_name(line) {
            sections.push((name, &data[start..at.saturating_sub(1).max(start)]));
            (name, start) = (next, at + line.len());
        }
        at += line.len();
    }
    sections.push((name, &data[start..]));
    sections
}

/// The name a line `#--NAME--` gives its section (a plain name: 1–32 letters, digits, `.`,
/// `_`, `-`, not starting with `.`).
fn section_name(line: &[u8]) -> Option<&str> {
    let line = line.strip_suffix(b"\n").unwrap_or(line);
    let name = std::str::from_utf8(line.strip_prefix(b"#--")?.strip_suffix(b"--")?).ok()?;
    let plain = name
        .bytes()
        .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b));
    ((1..=32).contains(&name.len()) && !name.starts_with('.') && plain).then_some(name)
}

/// A fuzz target: the scratch folder and the input; whether the input was accepted all the
/// way (built, opened, read intact) — what the seeds must be, and what a fuzzer need not be.
pub type Target = fn(&Scratch, &[u8]) -> bool;

/// Every target by name (the names of `fuzz/fuzz_targets/*.rs` and of their corpora).
pub const TARGETS: [(&str, Target); 12] = [
    ("run_config", files::run_config),
    ("plant_file", files::plant_file),
    ("prescription", files::prescription),
    ("sag_grid", files::sag_grid),
    ("controller_file", files::controller_file),
    ("frf_csv", files::frf_csv),
    ("deployment", deployment::from_toml),
    ("c_abi_open_toml", deployment::c_abi_open_toml),
    ("pil_image", deployment::image),
    ("pil_link", link::frames),
    ("mcap", recording::mcap),
    ("live_view", live_view::messages),
];

/// The target called `name`.
pub fn target(name: &str) -> Option<Target> {
    TARGETS.iter().find(|(n, _)| *n == name).map(|&(_, t)| t)
}

#[cfg(test)]
mod tests {
    use super::split_sections;

    #[test]
    fn sections_split_at_their_marker_lines() {
        let data = b"a = 1\n#--grid.csv--\n0,1\n2,3\n#--../x--\nb\n#--m.toml--\nc = 2\n";
        let s = split_sections(data);
        assert_eq!(s.len(), 3);
        assert_eq!(s[0], ("", &b"a = 1"[..]));
        assert_eq!(s[1], ("grid.csv", &b"0,1\n2,3\n#--../x--\nb"[..]));
        assert_eq!(s[2], ("m.toml", &b"c = 2\n"[..]));
        assert_eq!(split_sections(b"plain"), vec![("", &b"plain"[..])]);
    }
}
