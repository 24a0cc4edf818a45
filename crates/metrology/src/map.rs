//! A measured surface map: heights on a rectangular pixel grid, missing pixels kept missing.

use serde::Serialize;

/// A pixel reads the mean height over its area: taken as this many points per side (an
/// instrument's lateral resolution, as the simulated instrument makes it and the registration
/// models it).
pub(crate) const PIXEL_SUBSAMPLES: usize = 3;

/// The offsets, in pixels, of the `n × n` points a pixel's mean is taken over.
pub(crate) fn pixel_points(n: usize) -> impl Iterator<Item = (f64, f64)> {
    (0..n * n).map(move |k| {
        let at = |i: usize| (i as f64 + 0.5) / n as f64 - 0.5;
        (at(k % n), at(k / n))
    })
}

/// A part placed on an instrument: its centre at `decentre_m` in the instrument's frame and
/// turned by `rotation_rad` about the axis.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Placement {
    decentre_m: [f64; 2],
    sin: f64,
    cos: f64,
}

impl Placement {
    pub(crate) fn new(decentre_m: [f64; 2], rotation_rad: f64) -> Self {
        Placement {
            decentre_m,
            sin: libm::sin(rotation_rad),
            cos: libm::cos(rotation_rad),
        }
    }

    /// The part's point seen at `(u, v)` in the instrument's frame, m.
    pub(crate) fn part_point(&self, u: f64, v: f64) -> (f64, f64) {
        let (wx, wy) = (u - self.decentre_m[0], v - self.decentre_m[1]);
        (
            self.cos * wx + self.sin * wy,
            -self.sin * wx + self.cos * wy,
        )
    }

    /// Where the part's point `(x, y)` lies in the instrument's frame, m.
    pub(crate) fn instrument_point(&self, x: f64, y: f64) -> (f64, f64) {
        (
            self.cos * x - self.sin * y + self.decentre_m[0],
            self.sin * x + self.cos * y + self.decentre_m[1],
        )
    }

    /// `∂/∂decentre` of a height seen through the placement whose gradient in the part's
    /// frame is `(gx, gy)`.
    pub(crate) fn decentre_sensitivity(&self, gx: f64, gy: f64) -> [f64; 2] {
        [
            -(gx * self.cos - gy * self.sin),
            -(gx * self.sin + gy * self.cos),
        ]
    }
}

/// Bilinear interpolation in a row-major `rows × cols` grid at the fractional column `col`
/// and row `row` (NaN beyond the grid, or beside a node without a value).
pub(crate) fn bilinear(values: &[f64], rows: usize, cols: usize, col: f64, row: f64) -> f64 {
    if !(col >= 0.0 && row >= 0.0 && col <= (cols - 1) as f64 && row <= (rows - 1) as f64) {
        return f64::NAN;
    }
    let (i, j) = ((col as usize).min(cols - 2), (row as usize).min(rows - 2));
    let (tx, ty) = (col - i as f64, row - j as f64);
    let v = |r: usize, c: usize| values[r * cols + c];
    (1.0 - ty) * ((1.0 - tx) * v(j, i) + tx * v(j, i + 1))
        + ty * ((1.0 - tx) * v(j + 1, i) + tx * v(j + 1, i + 1))
}

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

    /// The height at `(x, y)` in the instrument's frame (m), bilinear between the four pixels
    /// around it (NaN beyond the map or beside a pixel without data).
    pub fn at(&self, x: f64, y: f64) -> f64 {
        let col = x / self.pitch_m[0] + (self.cols as f64 - 1.0) / 2.0;
        let row = (self.rows as f64 - 1.0) / 2.0 - y / self.pitch_m[1];
        bilinear(&self.heights_m, self.rows, self.cols, col, row)
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
