//! Reading a recording back with the official `mcap` crate.

use crate::frame::{Frame, Telemetry, Truth};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Read errors.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReadError {
    /// The file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// Path.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The file is not a valid MCAP.
    #[error("{path} is not a valid MCAP file: {source}")]
    Mcap {
        /// Path.
        path: PathBuf,
        /// Cause.
        source: mcap::McapError,
    },
    /// A message could not be decoded.
    #[error("{path}: bad {topic} message #{index}")]
    Decode {
        /// Path.
        path: PathBuf,
        /// Topic.
        topic: String,
        /// Message index on that topic.
        index: u64,
    },
}

/// A whole recording: metadata and frames in time order.
#[derive(Debug, Clone, Default)]
pub struct Recording {
    /// The `run` metadata record.
    pub metadata: BTreeMap<String, String>,
    /// One frame per recorded tick.
    pub frames: Vec<Frame>,
    /// Total messages read.
    pub messages: u64,
}

/// Reads `path` completely.
pub fn read(path: &Path) -> Result<Recording, ReadError> {
    let bytes = std::fs::read(path).map_err(|source| ReadError::Io {
        path: path.to_owned(),
        source,
    })?;
    let mc = |source| ReadError::Mcap {
        path: path.to_owned(),
        source,
    };
    let mut rec = Recording::default();
    if let Some(summary) = mcap::Summary::read(&bytes).map_err(mc)? {
        for idx in &summary.metadata_indexes {
            let m = mcap::read::metadata(&bytes, idx).map_err(mc)?;
            if m.name == "run" {
                rec.metadata = m.metadata;
            }
        }
    }
    let (mut telemetry, mut truth, mut times) = (Vec::new(), Vec::new(), Vec::new());
    for message in mcap::MessageStream::new(&bytes).map_err(mc)? {
        let message = message.map_err(mc)?;
        rec.messages += 1;
        let bad = |index: usize| ReadError::Decode {
            path: path.to_owned(),
            topic: message.channel.topic.clone(),
            index: index as u64,
        };
        match message.channel.topic.as_str() {
            Telemetry::TOPIC => {
                times.push(message.log_time);
                telemetry
                    .push(Telemetry::decode(&message.data).ok_or_else(|| bad(telemetry.len()))?)
            }
            Truth::TOPIC => {
                truth.push(Truth::decode(&message.data).ok_or_else(|| bad(truth.len()))?)
            }
            _ => {}
        }
    }
    rec.frames = times
        .into_iter()
        .zip(telemetry)
        .zip(truth)
        .map(|((time_ns, telemetry), truth)| Frame {
            time_ns,
            telemetry,
            truth,
        })
        .collect();
    Ok(rec)
}
