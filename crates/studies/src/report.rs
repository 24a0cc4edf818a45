//! How every study writes its results: data (CSV with a header naming column and unit, JSON),
//! all in one output directory, the pictures beside them (PNG + SVG, the `reports` crate).

use std::path::{Path, PathBuf};

/// Report errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// Writing a file failed.
    #[error("cannot write {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
}

/// Writes `text` to `path`; the path written.
pub fn write_file(path: PathBuf, text: &str) -> Result<PathBuf, ReportError> {
    std::fs::write(&path, text).map_err(|source| ReportError::Io {
        path: path.clone(),
        source,
    })?;
    Ok(path)
}

/// Creates `dir` and writes `files` (file name, contents) into it.
pub fn write_files(dir: &Path, files: &[(&str, &str)]) -> Result<Written, ReportError> {
    std::fs::create_dir_all(dir).map_err(|source| ReportError::Io {
        path: dir.to_owned(),
        source,
    })?;
    Ok(Written {
        files: files
            .iter()
            .map(|(name, text)| write_file(dir.join(name), text))
            .collect::<Result<_, _>>()?,
        note: None,
    })
}

/// What, when and by which tool and command a JSON file was written: the `metadata` object
/// that opens every JSON file of a study (what the result was made for — plant, rate,
/// controller — is in the result itself where it applies).
#[derive(serde::Serialize)]
struct Metadata<'a> {
    what: &'a str,
    written_utc: String,
    tool: String,
    command: String,
}

/// Pretty JSON of an analysis result `value` (what it is: `what`), opened by its
/// metadata (what, when, which tool and command); a result that is a list goes under `key`.
pub fn to_json<T: serde::Serialize + ?Sized>(what: &str, key: &str, value: &T) -> String {
    let metadata = Metadata {
        what,
        written_utc: humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string(),
        tool: concat!("fts-servo ", env!("CARGO_PKG_VERSION")).to_owned(),
        command: std::env::args().collect::<Vec<_>>().join(" "),
    };
    let mut out = serde_json::Map::new();
    out.insert(
        "metadata".into(),
        serde_json::to_value(&metadata).expect("metadata serialises"),
    );
    match serde_json::to_value(value).expect("analysis results serialise") {
        serde_json::Value::Object(fields) => out.extend(fields),
        other => {
            out.insert(key.into(), other);
        }
    }
    serde_json::to_string_pretty(&out).expect("JSON values serialise")
}

/// Creates `dir` and writes the data files `<stem>.csv` and `<stem>.json` (of `what`).
pub fn data<T: serde::Serialize + ?Sized>(
    dir: &Path,
    stem: &str,
    what: &str,
    csv: &str,
    json: &T,
) -> Result<Written, ReportError> {
    write_files(
        dir,
        &[
            (&format!("{stem}.csv"), csv),
            (&format!("{stem}.json"), &to_json(what, stem, json)),
        ],
    )
}

/// Files written, and a note if plots were skipped.
#[derive(Debug, Default)]
pub struct Written {
    /// Paths written.
    pub files: Vec<PathBuf>,
    /// Why plots were skipped, if they were.
    pub note: Option<String>,
}
