//! A measured surface map: heights on a rectangular pixel grid, missing pixels kept missing.

use serde::Serialize;

/// A pixel reads the mean height over its area: taken as this many points per side (an
/// instrument's lateral resolution, as the simulated instrument makes it and the registration
/// models it).
pub(crate) const PIXEL_SUBSAMPLES: usize = 3;

/// A length unit a map's heights or pitch may be written in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum LengthUnit {
    /// Metres.
    Metre,
    /// Millimetres.
    Millimetre,
    /// Micrometres.
    Micrometre,
    /// Nanometres.
    Nanometre,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::Metre => 1.0,
            LengthUnit::Millimetre => 1e-3,
            LengthUnit::Micrometre => 1e-6,
            LengthUnit::Nanometre => 1e-9,
        }
    }

    /// The unit named `s` (`m`, `mm`, `um` or `µm`, `nm`).
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "m" => Some(LengthUnit::Metre),
            "mm" => Some(LengthUnit::Millimetre),
            "um" | "µm" => Some(LengthUnit::Micrometre),
            "nm" => Some(LengthUnit::Nanometre),
            _ => None,
        }
    }
}

/// The file formats a map is read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum MapFormat {
    /// Zygo Mx `.datx` (HDF5).
    ZygoDatx,
    /// Zygo MetroPro binary `.dat`.
    MetroProDat,
    /// Zygo `XYZ Data File - Format 1` text.
    ZygoXyz,
    /// NumPy `.npy` (a 2-D float array).
    Npy,
    /// A comma-separated grid (fts-servo's sag grids, or any grid with the units given).
    CsvGrid,
}

/// Heights in m on a `rows × cols` grid, row-major, **row 0 at +y and column 0 at −x** (the
/// instrument's image order, as Zemax's grids); a height is the surface's height toward the
/// instrument (which faces the part as the tool did), NaN where the instrument has no data.
/// Pixel `(row, col)` lies at `x = (col − (cols − 1)/2)·pitch_x`, `y = ((rows − 1)/2 − row)·pitch_y`
/// in the instrument's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredMap {
    /// Rows (along −y).
    pub rows: usize,
    /// Columns (along +x).
    pub cols: usize,
    /// Pixel pitch along x and y, m.
    pub pitch_m: [f64; 2],
    /// Heights, m (NaN: no data).
    pub heights_m: Vec<f64>,
    /// The format it was read from.
    pub format: MapFormat,
    /// The instrument's wavelength where the file states it, m.
    pub wavelength_m: Option<f64>,
}

impl MeasuredMap {
    /// Pixel `i`'s position in the instrument's frame, m.
    pub fn xy(&self, i: usize) -> (f64, f64) {
        let (row, col) = (i / self.cols, i % self.cols);
        (
            (col as f64 - (self.cols as f64 - 1.0) / 2.0) * self.pitch_m[0],
            ((self.rows as f64 - 1.0) / 2.0 - row as f64) * self.pitch_m[1],
        )
    }

    /// The valid pixels: their positions (m) and heights (m).
    pub fn valid(&self) -> Vec<(f64, f64, f64)> {
        self.heights_m
            .iter()
            .enumerate()
            .filter(|(_, h)| h.is_finite())
            .map(|(i, &h)| {
                let (x, y) = self.xy(i);
                (x, y, h)
            })
            .collect()
    }
}
