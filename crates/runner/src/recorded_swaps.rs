//! Controllers swapped into a running loop (`servo ctl load`), as a recording keeps them: each
//! loaded file attached (`controller_load.N.toml`, written with the `end` record) and noted in
//! the `end` record with the tick it took the loop at and its SHA-256 — so a recording of a
//! run that changed controllers still says, on its own, which controller ran when.

use crate::config::sha256_hex;
use crate::error::RunError;
use crate::recording::input_key;
use recorder::{Input, Recorder, Visit};
use std::collections::BTreeMap;
use std::path::Path;

/// Swapped-in controller files a recording attaches (each ≤ 64 KiB, the contract's bound);
/// later swaps are noted in the `end` record with their hash only.
pub const MAX_ATTACHED_SWAPS: usize = 64;

/// A controller that took over a running loop.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Swap {
    /// The tick it took the loop at.
    pub tick: u64,
    /// The loaded file (a `[controller]` fragment), as sent; empty for a swap beyond
    /// [`MAX_ATTACHED_SWAPS`] (only its hash is kept).
    pub file: Vec<u8>,
    /// The file's SHA-256, hex.
    pub sha256: String,
    /// The file's size in bytes.
    pub bytes: usize,
}

impl Swap {
    /// The `n`-th swap (from 1): `file` took the loop at `tick`; the file is kept while `n` is
    /// within [`MAX_ATTACHED_SWAPS`].
    pub fn new(n: usize, tick: u64, file: &[u8]) -> Self {
        Swap {
            tick,
            file: if n <= MAX_ATTACHED_SWAPS {
                file.to_vec()
            } else {
                Vec::new()
            },
            sha256: sha256_hex(file),
            bytes: file.len(),
        }
    }

    /// The attachment name of the `n`-th swap (from 1).
    pub fn attachment_name(n: usize) -> String {
        format!("controller_load.{n}.toml")
    }

    /// The `end` record key holding the tick of the `n`-th swap.
    fn tick_key(n: usize) -> String {
        format!("controller_load.{n}.tick")
    }

    /// Notes the `n`-th swap in `end` (its tick, and for a reader the file's SHA-256 and size
    /// and the closed loop's spectral radius `checked_radius` on the run's model) and
    /// attaches its file to `rec` (up to [`MAX_ATTACHED_SWAPS`]), at its run time on a loop
    /// of `period_s`.
    pub fn record(
        &self,
        n: usize,
        period_s: f64,
        checked_radius: f64,
        end: &mut BTreeMap<String, String>,
        rec: Option<&mut Recorder>,
    ) {
        let sha = &self.sha256;
        end.insert(
            format!("controller_load.{n}"),
            format!(
                "tick {}: controller file sha256 {sha} ({} bytes), closed-loop spectral radius {}",
                self.tick, self.bytes, checked_radius
            ),
        );
        end.insert(Self::tick_key(n), self.tick.to_string());
        if let Some(rec) = rec.filter(|_| n <= MAX_ATTACHED_SWAPS) {
            let name = Self::attachment_name(n);
            end.insert(input_key(&name), sha.clone());
            let at_ns = (self.tick as f64 * period_s * 1e9).round() as u64;
            rec.attach(
                Input {
                    name,
                    media_type: "application/toml".into(),
                    data: self.file.clone(),
                },
                at_ns,
            );
        }
    }

    /// The swaps recorded in the finished recording `path`, in order, each file checked
    /// against the SHA-256 its `end` record states (read through the file's index: the frames
    /// are not read). Empty for a run without swaps or an unfinished file (it has no `end`
    /// record); a swap noted without its file (beyond [`MAX_ATTACHED_SWAPS`]) ends the list.
    pub fn read_all(path: &Path) -> Result<Vec<Swap>, RunError> {
        #[derive(Default)]
        struct Found {
            end: BTreeMap<String, String>,
            files: BTreeMap<String, Vec<u8>>,
        }
        impl Visit for Found {
            fn metadata(&mut self, name: &str, values: &BTreeMap<String, String>) {
                if name == "end" {
                    self.end = values.clone();
                }
            }
            fn attachment(&mut self, name: &str, data: &[u8]) {
                if name.starts_with("controller_load.") {
                    self.files.insert(name.to_owned(), data.to_vec());
                }
            }
        }
        let mut found = Found::default();
        if !recorder::visit_indexed(path, &mut found)? {
            return Ok(Vec::new());
        }
        let mut swaps = Vec::new();
        for n in 1.. {
            let name = Self::attachment_name(n);
            let (Some(tick), Some(file)) =
                (found.end.get(&Self::tick_key(n)), found.files.remove(&name))
            else {
                break;
            };
            let mismatch = || RunError::InputMismatch {
                path: path.to_owned(),
                input: name.clone(),
            };
            if found.end.get(&input_key(&name)) != Some(&sha256_hex(&file)) {
                return Err(mismatch());
            }
            swaps.push(Swap {
                tick: tick.parse().map_err(|_| mismatch())?,
                sha256: sha256_hex(&file),
                bytes: file.len(),
                file,
            });
        }
        Ok(swaps)
    }
}
