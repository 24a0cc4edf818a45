//! What operators did to a running loop, as its recording keeps it: each controller swapped in
//! (`servo ctl load`) attached (`controller_load.N.toml`, written with the `end` record) and
//! noted with the tick it took the loop at and its SHA-256, and each gain change (`servo ctl
//! gain`) with its tick and scale — so a recording of a run that was steered still says, on its
//! own, which controller ran when and at what gain.

use crate::error::RunError;
use crate::recording::input_key;
use recorder::{Input, Recorder, Visit};
use run_config::sha256_hex;
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
    /// The file's size in bytes (as kept: 0 beyond [`MAX_ATTACHED_SWAPS`] when read back).
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
        let name = Self::attachment_name(n);
        end.insert(input_key(&name), sha.clone());
        if let Some(rec) = rec.filter(|_| n <= MAX_ATTACHED_SWAPS) {
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
}

/// A gain change (`servo ctl gain`) a running loop applied.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GainChange {
    /// The tick it took effect at.
    pub tick: u64,
    /// The new scale on the controller output, dimensionless.
    pub scale: f64,
}

impl GainChange {
    /// The `end` record key holding the tick of the `n`-th change.
    fn tick_key(n: usize) -> String {
        format!("gain_change.{n}.tick")
    }

    /// The `end` record key holding the scale of the `n`-th change.
    fn scale_key(n: usize) -> String {
        format!("gain_change.{n}.scale")
    }

    /// Notes the `n`-th change (from 1) in `end`: readably, and its tick and scale on keys of
    /// their own.
    pub fn record(&self, n: usize, end: &mut BTreeMap<String, String>) {
        end.insert(
            format!("gain_change.{n}"),
            format!("tick {}: output scale {}", self.tick, self.scale),
        );
        end.insert(Self::tick_key(n), self.tick.to_string());
        end.insert(Self::scale_key(n), self.scale.to_string());
    }
}

/// Everything operators did to a recorded run, in order of kind.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OperatorLog {
    /// Controllers swapped in.
    pub swaps: Vec<Swap>,
    /// Gain changes applied.
    pub gain_changes: Vec<GainChange>,
}

impl OperatorLog {
    /// The first tick an operator changed the loop at (a swap or a gain change), if any: up
    /// to it, the run is its configuration's alone.
    pub fn first_tick(&self) -> Option<u64> {
        let swaps = self.swaps.iter().map(|s| s.tick);
        swaps.chain(self.gain_changes.iter().map(|g| g.tick)).min()
    }

    /// The log of the finished recording `path`, read through the file's index (the frames
    /// are not read): each swap's file checked against the SHA-256 its `end` record states.
    /// Empty for an unsteered run or an unfinished file (it has no `end` record); a swap beyond
    /// [`MAX_ATTACHED_SWAPS`] comes with its tick and an empty file (none was attached).
    pub fn read(path: &Path) -> Result<Self, RunError> {
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
            return Ok(Self::default());
        }
        let mut swaps = Vec::new();
        for n in 1.. {
            let name = Swap::attachment_name(n);
            let Some(tick) = found.end.get(&Swap::tick_key(n)) else {
                break;
            };
            let mismatch = || RunError::InputMismatch {
                path: path.to_owned(),
                input: name.clone(),
            };
            let sha256 = found.end.get(&input_key(&name)).ok_or_else(mismatch)?;
            let file = found.files.remove(&name).unwrap_or_default();
            let attached = n <= MAX_ATTACHED_SWAPS;
            if attached && *sha256 != sha256_hex(&file) {
                return Err(mismatch());
            }
            swaps.push(Swap {
                tick: tick.parse().map_err(|_| mismatch())?,
                sha256: sha256.clone(),
                bytes: file.len(),
                file,
            });
        }
        let gain_changes = (1..)
            .map_while(|n| {
                let tick = found.end.get(&GainChange::tick_key(n))?.parse().ok()?;
                let scale = found.end.get(&GainChange::scale_key(n))?.parse().ok()?;
                Some(GainChange { tick, scale })
            })
            .collect();
        Ok(OperatorLog {
            swaps,
            gain_changes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Swaps and gain changes written the way the recorder writes them read back the same; the
    /// swaps beyond the attachment limit keep their tick and hash, not their file.
    #[test]
    fn a_steered_runs_log_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("steered.mcap");
        let mut rec = Recorder::create(&path, BTreeMap::new(), Default::default()).unwrap();
        rec.push(recorder::Frame::default()).unwrap();
        let file = |n: usize| format!("[controller.pid]\nkp = {n}.0\n").into_bytes();
        let mut end = BTreeMap::new();
        let written: Vec<Swap> = (1..=MAX_ATTACHED_SWAPS + 2)
            .map(|n| Swap::new(n, 1000 * n as u64, &file(n)))
            .collect();
        for (i, s) in written.iter().enumerate() {
            s.record(i + 1, 1e-5, 0.99, &mut end, Some(&mut rec));
        }
        let change = GainChange {
            tick: 1500,
            scale: 0.8,
        };
        change.record(1, &mut end);
        rec.finish(end).unwrap();

        let log = OperatorLog::read(&path).unwrap();
        assert_eq!(log.gain_changes, vec![change]);
        assert_eq!(log.first_tick(), Some(1000));
        assert_eq!(log.swaps.len(), written.len());
        for (n, (read, wrote)) in (1..).zip(log.swaps.iter().zip(&written)) {
            assert_eq!(
                (read.tick, &read.sha256),
                (wrote.tick, &sha256_hex(&file(n)))
            );
            let attached = n <= MAX_ATTACHED_SWAPS;
            assert_eq!(read.file.is_empty(), !attached, "swap {n}");
            if attached {
                assert_eq!(read.file, file(n));
            }
        }
    }
}
