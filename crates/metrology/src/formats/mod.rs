//! Reading a map from a file: the format from the file's extension, units and pitch from the
//! file where it states them, from [`ReadOptions`] where it does not; every size bounded.

mod csv;
mod datx;
mod metropro;
mod npy;
mod write;
mod xyz;

pub use write::to_zygo_xyz;

use crate::map::{LengthUnit, MapFormat, MeasuredMap};
use crate::MapError;
use std::path::Path;

/// The largest map file read, bytes.
pub const MAX_MAP_BYTES: u64 = 1 << 30;

/// The most pixels a map may have (4096 × 4096).
pub const MAX_PIXELS: usize = 4096 * 4096;

/// What the user states of a map whose file does not: keys `map.height_unit` and `map.pitch_m`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReadOptions {
    /// The heights' unit, for files that do not state it (`.npy`, a bare CSV grid).
    pub height_unit: Option<LengthUnit>,
    /// The pixel pitch, m, for files that do not state it.
    pub pitch_m: Option<f64>,
}

/// What a reader found in a file before the options fill the gaps.
struct Raw {
    rows: usize,
    cols: usize,
    /// Heights in the file's unit (NaN: no data).
    heights: Vec<f64>,
    /// The file's height unit, metres per unit (None: not stated).
    unit_m: Option<f64>,
    /// The file's pitch, m (None: not stated).
    pitch_m: Option<[f64; 2]>,
    wavelength_m: Option<f64>,
}

/// Reads the map in `path` (`.datx`, `.dat`, `.xyz`, `.npy` or `.csv`).
pub fn read_map(path: &Path, options: &ReadOptions) -> Result<MeasuredMap, MapError> {
    let err = |reason: String| MapError::new(path, reason);
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let format = match ext.as_str() {
        "datx" => MapFormat::ZygoDatx,
        "dat" => MapFormat::MetroProDat,
        "xyz" => MapFormat::ZygoXyz,
        "npy" => MapFormat::Npy,
        "csv" => MapFormat::CsvGrid,
        _ => {
            return Err(err(format!(
                "unknown map format '.{ext}' (allowed: .datx, .dat, .xyz, .npy, .csv)"
            )))
        }
    };
    let bytes = daq_io::input_file::read_regular(path, MAX_MAP_BYTES)
        .map_err(|e| err(format!("cannot read it: {e}")))?;
    let raw = match format {
        MapFormat::ZygoDatx => datx::read(bytes),
        MapFormat::MetroProDat => metropro::read(&bytes),
        MapFormat::ZygoXyz => text(bytes).and_then(|t| xyz::read(&t)),
        MapFormat::Npy => npy::read(&bytes),
        MapFormat::CsvGrid => text(bytes).and_then(|t| csv::read(&t)),
    }
    .map_err(err)?;
    finish(raw, format, options).map_err(err)
}

/// The file's bytes as UTF-8 text.
fn text(bytes: Vec<u8>) -> Result<String, String> {
    String::from_utf8(bytes).map_err(|_| "not UTF-8 text".to_string())
}

/// Checks a grid's size: at least 2 × 2, at most [`MAX_PIXELS`].
fn check_size(rows: usize, cols: usize) -> Result<(), String> {
    if rows < 2 || cols < 2 || rows.saturating_mul(cols) > MAX_PIXELS {
        return Err(format!(
            "a map of {rows} × {cols} pixels (allowed: at least 2 × 2, at most {MAX_PIXELS} pixels)"
        ));
    }
    Ok(())
}

/// The map in m: the file's unit and pitch, else the options'; an option the file already
/// states is refused (the file's word stands).
fn finish(raw: Raw, format: MapFormat, o: &ReadOptions) -> Result<MeasuredMap, String> {
    check_size(raw.rows, raw.cols)?;
    let unit_m = match (raw.unit_m, o.height_unit) {
        (Some(_), Some(_)) => {
            return Err("map.height_unit: the file states its heights' unit; leave it unset".into())
        }
        (Some(u), None) => u,
        (None, Some(u)) => u.metres(),
        (None, None) => {
            return Err(
                "the file does not state its heights' unit: set map.height_unit (m, mm, um, nm)"
                    .into(),
            )
        }
    };
    let pitch_m = match (raw.pitch_m, o.pitch_m) {
        (Some(p), Some(_)) => {
            return Err(format!(
                "map.pitch_m: the file states its pixel pitch ({:.6} mm); leave it unset",
                p[0] * 1e3
            ))
        }
        (Some(p), None) => p,
        (None, Some(p)) if p.is_finite() && p > 0.0 && p <= 1.0 => [p, p],
        (None, Some(p)) => return Err(format!("map.pitch_m = {p}: allowed 0 < pitch ≤ 1 m")),
        (None, None) => {
            return Err("the file does not state its pixel pitch: set map.pitch_m (m)".into())
        }
    };
    if !pitch_m
        .iter()
        .all(|p| p.is_finite() && *p > 0.0 && *p <= 1.0)
    {
        return Err(format!(
            "the file's pixel pitch {pitch_m:?} m is outside 0 < pitch ≤ 1 m"
        ));
    }
    let heights_m: Vec<f64> = raw.heights.iter().map(|h| h * unit_m).collect();
    if let Some(bad) = heights_m.iter().find(|h| h.is_finite() && h.abs() > 1.0) {
        return Err(format!("a height of {bad} m: beyond ±1 m (a wrong unit?)"));
    }
    Ok(MeasuredMap {
        rows: raw.rows,
        cols: raw.cols,
        pitch_m,
        heights_m,
        format,
        wavelength_m: raw.wavelength_m,
    })
}
