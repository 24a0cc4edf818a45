//! What goes wrong writing a recording or an export.

use std::path::PathBuf;

/// Recording errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RecordError {
    /// The output file could not be created or written (a full disk, an I/O error).
    #[error("cannot write {path}: {source}")]
    Io {
        /// Output path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// Writing failed mid-run (a full disk, a file size limit, a quota, an I/O error): the run
    /// ends. The recording is finished with the part that fit (cut back to a chunk boundary
    /// until its end records fit) — or, when even that cannot be written, left unfinished
    /// with everything up to its last complete chunk.
    #[error("writing {} failed: {source}; {kept}", path.display())]
    WriteFailed {
        /// The target.
        path: PathBuf,
        /// What was kept, and where.
        kept: Kept,
        /// Cause.
        source: std::io::Error,
    },
    /// The target exists and [`Overwrite::Refuse`] was asked for.
    #[error("{} exists: not overwritten (set overwrite to replace it)", path.display())]
    Exists {
        /// The target.
        path: PathBuf,
    },
    /// The writer thread stopped early (its error is reported by [`Recorder::finish`]).
    #[error("the recorder thread stopped")]
    WriterGone,
}

/// What a recording whose writing failed kept.
#[derive(Debug, Clone, PartialEq)]
pub enum Kept {
    /// Finished at `path`, shorter: the run up to `until_s` of run time.
    Finished {
        /// The recording.
        path: PathBuf,
        /// Run time of its last recorded tick, s.
        until_s: f64,
    },
    /// Unfinished at `partial`: everything up to its last complete chunk.
    Unfinished {
        /// The unfinished file.
        partial: PathBuf,
    },
}

impl std::fmt::Display for Kept {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Kept::Finished { path, until_s } => write!(
                f,
                "the recording was finished with the part that fit (the run up to {until_s:.3} s) in {}",
                path.display()
            ),
            Kept::Unfinished { partial } => write!(
                f,
                "the recording up to its last complete chunk is in {} (`servo inspect` recovers it)",
                partial.display()
            ),
        }
    }
}
