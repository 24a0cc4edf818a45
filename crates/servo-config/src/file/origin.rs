//! Where a configuration came from, and errors that name the file, line, key and allowed
//! range.

use crate::check::Invalid;
use std::path::{Path, PathBuf};

/// Configuration errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConfigError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// TOML syntax, unknown key or wrong type (the message carries line and column).
    #[error("{path}: {message}")]
    Parse {
        /// File.
        path: PathBuf,
        /// The parser's message, with line, column and the offending key.
        message: String,
    },
    /// A value outside its allowed range.
    #[error("{}{key} = {value}: allowed {range}", location(path, line))]
    Invalid {
        /// File, if the value came from one.
        path: Option<PathBuf>,
        /// 1-based line of the key in the file, if found.
        line: Option<usize>,
        /// Dotted key.
        key: String,
        /// The value, printed.
        value: String,
        /// Allowed range.
        range: String,
    },
}

/// A TOML parser's error as `line L, column C: message` — the position and what was expected,
/// never the file's content (the parser's own excerpt would echo a line of whatever file the
/// path turned out to be, a key file behind a symlink included).
pub fn toml_message(text: &str, e: &toml::de::Error) -> String {
    match e.span() {
        Some(span) => {
            let before = &text[..span.start.min(text.len())];
            let line = before.matches('\n').count() + 1;
            let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
            format!("line {line}, column {column}: {}", e.message().trim_end())
        }
        None => e.message().trim_end().to_owned(),
    }
}

fn location(path: &Option<PathBuf>, line: &Option<usize>) -> String {
    match (path, line) {
        (Some(p), Some(l)) => format!("{}:{l}: ", p.display()),
        (Some(p), None) => format!("{}: ", p.display()),
        _ => String::new(),
    }
}

/// Where a configuration came from: the file and its text, to locate errors at their line
/// and to resolve relative paths against the file's folder.
#[derive(Debug, Clone, Default)]
pub struct Origin {
    /// The file, if any.
    pub path: Option<PathBuf>,
    /// The file's text, if any.
    pub text: Option<String>,
}

impl Origin {
    /// An invalid-value error located in the file when the key is there.
    pub fn invalid(&self, key: &str, value: impl std::fmt::Display, range: &str) -> ConfigError {
        ConfigError::Invalid {
            path: self.path.clone(),
            line: self.text.as_deref().and_then(|t| line_of(t, key)),
            key: key.to_owned(),
            value: value.to_string(),
            range: range.to_owned(),
        }
    }

    /// `invalid` (a key checked without allocation) located in this file.
    pub fn located(&self, invalid: &Invalid) -> ConfigError {
        let mut key = String::new();
        let _ = invalid.write_key(&mut key);
        let value = if matches!(invalid.allowed, crate::Allowed::Digest(_)) {
            "(does not match)".to_owned()
        } else if invalid.value.is_nan() {
            "(not a number, or missing)".to_owned()
        } else {
            invalid.value.to_string()
        };
        self.invalid(&key, value, &invalid.allowed.to_string())
    }

    /// Resolves a path from the config relative to the config file's directory.
    pub fn resolve(&self, p: &Path) -> PathBuf {
        match &self.path {
            Some(cfg) if p.is_relative() => cfg.parent().unwrap_or(Path::new(".")).join(p),
            _ => p.to_owned(),
        }
    }
}

/// The 1-based line where the dotted `key` is set in TOML `text`, if it is.
pub fn line_of(text: &str, key: &str) -> Option<usize> {
    let doc = toml_edit::ImDocument::parse(text).ok()?;
    let mut item = doc.as_item();
    for part in key.split('.') {
        item = item.get(part)?;
    }
    let span = item.span()?;
    Some(text[..span.start].matches('\n').count() + 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A parse error says where and what, and never quotes the file.
    #[test]
    fn parse_errors_name_the_position_not_the_content() {
        let text = "[run]\nduration_s = 2.0\n-----BEGIN SECRET-----\n";
        let e = toml::from_str::<toml::Table>(text).unwrap_err();
        let m = toml_message(text, &e);
        assert!(m.starts_with("line 3, column "), "{m}");
        assert!(!m.contains("SECRET"), "{m}");
    }

    #[test]
    fn line_numbers_of_keys() {
        let text = "[run]\nduration_s = 2.0\n\n[plant.stage]\nm1_kg = -1.0\n";
        assert_eq!(line_of(text, "run.duration_s"), Some(2));
        assert_eq!(line_of(text, "plant.stage.m1_kg"), Some(5));
        assert_eq!(line_of(text, "plant.stage.m2_kg"), None);
    }
}
