//! Cutting-force profiles on the tool tip (N, positive away from the workpiece), evaluated at
//! the start of each servo tick and held over it.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Thrust force (along the tool axis, which the FTS moves) per unit of uncut chip area in N/m²
/// (★ 5e9: the thesis gives no force; diamond turning of copper at sub-micrometre chip
/// thickness takes a specific energy of ≈ 5 GPa, and there the thrust force is about the
/// cutting force — Lucca, Rhorer & Komanduri, CIRP Annals 40 (1991) 69–72).
pub const SPECIFIC_THRUST_N_PER_M2: f64 = 5e9;

/// The thrust force of a cut taking `feed_m_per_rev` (m) per revolution at depth `depth_m` (m),
/// in N: the specific thrust times the chip area `feed × depth` (round-nose tool, depth ≫ f²/8R).
pub const fn thrust_force_n(specific_n_per_m2: f64, feed_m_per_rev: f64, depth_m: f64) -> f64 {
    specific_n_per_m2 * feed_m_per_rev * depth_m
}

/// The §7.6 intermittent cut's force while cutting in N: Table 7-3's 8 µm/rev feed and 2 µm
/// depth of cut in copper at [`SPECIFIC_THRUST_N_PER_M2`] (0.08 N).
pub const TABLE_7_3_FORCE_N: f64 = thrust_force_n(SPECIFIC_THRUST_N_PER_M2, 8e-6, 2e-6);

/// A cutting-force profile as configured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum CuttingProfile {
    /// No cutting.
    #[default]
    None,
    /// A constant force.
    Constant {
        /// Force in N.
        force_n: f64,
    },
    /// §7.6: a face cut over a workpiece with half its surface milled lower, so the tool cuts
    /// for half of each spindle revolution (a force step twice per revolution).
    IntermittentCut {
        /// Force while cutting in N (Table 7-3's cut: [`TABLE_7_3_FORCE_N`], 0.08 N).
        force_n: f64,
        /// Spindle speed in rpm (250, Table 7-3).
        spindle_rpm: f64,
    },
    /// §5.7.5 / §8.5.2 micro-lenslet: the tool oscillates sinusoidally and cuts at the far end
    /// of its stroke; the force follows the depth of cut (half the amplitude at the peak).
    Lenslet {
        /// Force at full depth in N (★ 2 N, "several newtons", §3.2).
        peak_force_n: f64,
        /// Tool oscillation frequency in Hz (100, Table 8-3).
        frequency_hz: f64,
    },
    /// A recorded force, `time_s,force_n` per line (header allowed), linearly interpolated and
    /// held at its last value.
    Csv {
        /// Path of the CSV file.
        path: PathBuf,
    },
}

/// Errors loading a profile.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum CuttingError {
    /// The CSV could not be read.
    #[error("cutting-force CSV {path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// A CSV line is malformed.
    #[error("cutting-force CSV {path}, line {line}: {reason}")]
    Parse {
        /// File.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A parameter is out of range.
    #[error("cutting.{key} = {value} must be {range}")]
    Parameter {
        /// Key.
        key: &'static str,
        /// Value.
        value: f64,
        /// Allowed range.
        range: &'static str,
    },
}

/// A profile ready for the tick: [`CuttingForce::at`] allocates nothing.
#[derive(Debug, Clone)]
pub struct CuttingForce {
    profile: CuttingProfile,
    samples: Vec<(f64, f64)>,
    cursor: usize,
}

impl CuttingForce {
    /// Validates `profile` and loads its data.
    pub fn new(profile: &CuttingProfile) -> Result<Self, CuttingError> {
        let finite = |key, value: f64, lo: f64, range| {
            if value.is_finite() && value >= lo {
                Ok(())
            } else {
                Err(CuttingError::Parameter { key, value, range })
            }
        };
        let samples = match profile {
            CuttingProfile::None => Vec::new(),
            CuttingProfile::Constant { force_n } => {
                finite("force_n", *force_n, f64::MIN, "finite")?;
                Vec::new()
            }
            CuttingProfile::IntermittentCut {
                force_n,
                spindle_rpm,
            } => {
                finite("force_n", *force_n, f64::MIN, "finite")?;
                finite("spindle_rpm", *spindle_rpm, 1e-3, "≥ 0.001 rpm")?;
                Vec::new()
            }
            CuttingProfile::Lenslet {
                peak_force_n,
                frequency_hz,
            } => {
                finite("peak_force_n", *peak_force_n, f64::MIN, "finite")?;
                finite("frequency_hz", *frequency_hz, 1e-6, "> 0 Hz")?;
                Vec::new()
            }
            CuttingProfile::Csv { path } => load_csv(path)?,
        };
        Ok(CuttingForce {
            profile: profile.clone(),
            samples,
            cursor: 0,
        })
    }

    /// Force in N at time `t_s`; call with non-decreasing times for O(1) CSV look-up.
    #[inline]
    pub fn at(&mut self, t_s: f64) -> f64 {
        match self.profile {
            CuttingProfile::None => 0.0,
            CuttingProfile::Constant { force_n } => force_n,
            CuttingProfile::IntermittentCut {
                force_n,
                spindle_rpm,
            } => {
                let revs = t_s * spindle_rpm / 60.0;
                if revs - revs.floor() < 0.5 {
                    force_n
                } else {
                    0.0
                }
            }
            CuttingProfile::Lenslet {
                peak_force_n,
                frequency_hz,
            } => {
                // Depth of cut = half the stroke: cutting while sin > ½, full depth at the peak.
                let s = libm::sin(2.0 * std::f64::consts::PI * frequency_hz * t_s);
                peak_force_n * ((s - 0.5) / 0.5).max(0.0)
            }
            CuttingProfile::Csv { .. } => self.interpolate(t_s),
        }
    }

    fn interpolate(&mut self, t: f64) -> f64 {
        let s = &self.samples;
        if t < s[self.cursor].0 {
            self.cursor = 0;
        }
        while self.cursor + 1 < s.len() && s[self.cursor + 1].0 <= t {
            self.cursor += 1;
        }
        let (t0, f0) = s[self.cursor];
        match s.get(self.cursor + 1) {
            Some(&(t1, f1)) if t >= t0 => f0 + (f1 - f0) * (t - t0) / (t1 - t0),
            _ => f0, // before the first sample or after the last: hold
        }
    }
}

/// Largest cutting-force CSV, bytes.
const MAX_CSV_BYTES: u64 = 256 << 20;

fn load_csv(path: &std::path::Path) -> Result<Vec<(f64, f64)>, CuttingError> {
    let text = daq_io::input_file::read_regular_text(path, MAX_CSV_BYTES).map_err(|source| {
        CuttingError::Io {
            path: path.to_path_buf(),
            source,
        }
    })?;
    let err = |line: usize, reason: String| CuttingError::Parse {
        path: path.to_path_buf(),
        line,
        reason,
    };
    let mut out: Vec<(f64, f64)> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut fields = line.split(',').map(str::trim);
        let (Some(a), Some(b), None) = (fields.next(), fields.next(), fields.next()) else {
            return Err(err(i + 1, "expected two columns `time_s,force_n`".into()));
        };
        let (Ok(t), Ok(f)) = (a.parse::<f64>(), b.parse::<f64>()) else {
            if out.is_empty() && i == 0 {
                continue; // header
            }
            return Err(err(i + 1, format!("not numbers: `{line}`")));
        };
        if !t.is_finite() || !f.is_finite() {
            return Err(err(i + 1, "non-finite value".into()));
        }
        if out.last().is_some_and(|&(t_prev, _)| t <= t_prev) {
            return Err(err(i + 1, "time must increase strictly".into()));
        }
        out.push((t, f));
    }
    if out.is_empty() {
        return Err(err(0, "no data rows".into()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intermittent_cut_is_half_a_revolution() {
        let mut c = CuttingForce::new(&CuttingProfile::IntermittentCut {
            force_n: 1.5,
            spindle_rpm: 250.0,
        })
        .unwrap();
        let rev = 60.0 / 250.0;
        assert_eq!(c.at(0.1 * rev), 1.5);
        assert_eq!(c.at(0.6 * rev), 0.0);
        assert_eq!(c.at(1.2 * rev), 1.5);
    }

    #[test]
    fn lenslet_force_follows_depth_of_cut() {
        let mut c = CuttingForce::new(&CuttingProfile::Lenslet {
            peak_force_n: 2.0,
            frequency_hz: 100.0,
        })
        .unwrap();
        assert!((c.at(0.0025) - 2.0).abs() < 1e-12); // stroke peak
        assert_eq!(c.at(0.0075), 0.0); // far side
    }

    #[test]
    fn csv_interpolates_and_reports_bad_lines() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let good = dir.join("good.csv");
        std::fs::write(&good, "time_s,force_n\n0,0\n1e-3,2\n2e-3,1\n").unwrap();
        let mut c = CuttingForce::new(&CuttingProfile::Csv { path: good }).unwrap();
        assert!((c.at(0.5e-3) - 1.0).abs() < 1e-12);
        assert!((c.at(1.5e-3) - 1.5).abs() < 1e-12);
        assert_eq!(c.at(5e-3), 1.0);
        let bad = dir.join("bad.csv");
        std::fs::write(&bad, "0,0\n1e-3,x\n").unwrap();
        let e = CuttingForce::new(&CuttingProfile::Csv { path: bad }).unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }
}
